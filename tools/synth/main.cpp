/// omnipose-synth: renders a synthetic dataset (DESIGN.md section 6) from an equirect photo,
/// with exact ground truth, through the exact renderer of omnipose::synth.

#include <charconv>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <optional>
#include <string>
#include <string_view>

#include "omnipose/synth.hpp"
#include "progress_line.hpp"

namespace {

using namespace omnipose;

constexpr const char* kUsage = R"(usage: omnipose-synth --texture PHOTO.jpg --out DIR [options]

Renders a synthetic omni-camera dataset (calibration.yaml, frames/, timestamps.txt,
groundtruth.tum) from an equirectangular photo, with exact ground truth.

  --texture PHOTO         equirectangular photo (2:1), converted to grey     (required)
  --out DIR               dataset directory; DIR/frames must be empty or new (required)
  --scene sphere|box      texture at infinity, or on a 6 x 5 m box room (floor -1 m,
                          ceiling +1.5 m); default: box if the motion translates
  --output omni|panorama  donut image of the lens (default) or the unwrapped panorama
  --motion MOTION.yaml    motion script (format: include/omnipose/synth.hpp,
                          example: tools/synth/examples/tour.yaml)
  --preset NAME           built-in motion: roll, pitch, yaw, mixed, translate, demo
                          (default: demo)
  --print-preset NAME     print a preset's motion script and exit
  --frames N              total frame count (segments are cycled or cut to fit)
  --seed S                seed of the motion and the degradations (default: the script's)
  --noise SIGMA           Gaussian sensor noise, grey levels (default 0)
  --blur SIGMA            Gaussian blur, pixels (default 0)
  --jpeg Q                write JPEG frames of quality Q (1..100); 0 = PNG (default)
  --exposure-jitter STD   per-frame gain 1 + N(0, STD), e.g. 0.05 (default 0)
  --exposure-offset STD   per-frame offset N(0, STD), grey levels (default 0)
  --calibration CAL.yaml  lens and panorama; default: 720x720, centre 359.5, radii
                          120/300, panorama 1100x110, horizon row 54.5
  --supersample K         K x K rays per pixel (default 3)
  --occluder ANGLE,WIDTH  paint a static mast/cable occluder over a sector of the ring
                          (image angle and width, degrees; omni output), the same in
                          every frame
  --write-mask            also write mask.png hiding the occluder (2 deg margin) and name
                          it in calibration.yaml (omni.mask)
  --quiet                 no progress line (it is shown only on a terminal anyway)
  -h, --help              this text
)";

/// A command-line mistake: reported with a hint to --help, exit code 2.
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

struct Args {
  std::string texture, out, motion, preset, print_preset, calibration;
  std::optional<synth::SceneKind> scene;
  synth::OutputKind output = synth::OutputKind::kOmni;
  std::optional<int> frames;
  std::optional<std::uint64_t> seed;
  double noise = 0.0, blur = 0.0, exposure_gain = 0.0, exposure_offset = 0.0;
  int jpeg = 0;
  int supersample = synth::RenderOptions{}.supersample;
  std::optional<synth::Occluder> occluder;
  bool write_mask = false;
  bool quiet = false;
  bool help = false;
};

template <typename T>
T parseNumber(std::string_view option, std::string_view text) {
  T value{};
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size()) {
    throw UsageError(std::string(option) + ": '" + std::string(text) + "' is not a valid number");
  }
  return value;
}

Args parseArgs(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string_view opt = argv[i];
    if (opt == "-h" || opt == "--help") {
      a.help = true;
      continue;
    }
    if (opt == "--write-mask") {
      a.write_mask = true;
      continue;
    }
    if (opt == "--quiet") {
      a.quiet = true;
      continue;
    }
    if (i + 1 >= argc) throw UsageError(std::string(opt) + ": unknown option or missing value");
    const std::string_view val = argv[++i];
    try {
      if (opt == "--texture") a.texture = val;
      else if (opt == "--out") a.out = val;
      else if (opt == "--scene") a.scene = synth::parseSceneKind(std::string(val));
      else if (opt == "--output") a.output = synth::parseOutputKind(std::string(val));
      else if (opt == "--motion") a.motion = val;
      else if (opt == "--preset") a.preset = val;
      else if (opt == "--print-preset") a.print_preset = val;
      else if (opt == "--frames") a.frames = parseNumber<int>(opt, val);
      else if (opt == "--seed") a.seed = parseNumber<std::uint64_t>(opt, val);
      else if (opt == "--noise") a.noise = parseNumber<double>(opt, val);
      else if (opt == "--blur") a.blur = parseNumber<double>(opt, val);
      else if (opt == "--jpeg") a.jpeg = parseNumber<int>(opt, val);
      else if (opt == "--exposure-jitter") a.exposure_gain = parseNumber<double>(opt, val);
      else if (opt == "--exposure-offset") a.exposure_offset = parseNumber<double>(opt, val);
      else if (opt == "--calibration") a.calibration = val;
      else if (opt == "--supersample") a.supersample = parseNumber<int>(opt, val);
      else if (opt == "--occluder") a.occluder = synth::parseOccluder(std::string(val));
      else throw UsageError(std::string(opt) + ": unknown option");
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string(opt) + ": " + e.what());
    }
  }
  if (a.help || !a.print_preset.empty()) return a;
  if (a.texture.empty()) throw UsageError("--texture is required");
  if (a.out.empty()) throw UsageError("--out is required");
  if (!a.motion.empty() && !a.preset.empty()) {
    throw UsageError("give --motion or --preset, not both");
  }
  if (a.frames && *a.frames < 1) throw UsageError("--frames: must be >= 1");
  if (a.jpeg < 0 || a.jpeg > 100) throw UsageError("--jpeg: must be in [0, 100]");
  if (a.write_mask && !a.occluder) throw UsageError("--write-mask needs --occluder");
  if (a.occluder && a.output != synth::OutputKind::kOmni)
    throw UsageError("--occluder paints the omni image: it needs --output omni");
  return a;
}

int run(const Args& a) {
  Calibration calibration =
      a.calibration.empty() ? Calibration{} : Calibration::load(a.calibration);
  const std::string motion_name = !a.motion.empty() ? a.motion
                                  : !a.preset.empty() ? "preset " + a.preset
                                                      : "preset demo";
  synth::MotionScript script = !a.motion.empty() ? synth::MotionScript::load(a.motion)
                               : synth::MotionScript::preset(a.preset.empty() ? "demo" : a.preset);
  if (a.frames) script.frames = *a.frames;
  if (a.seed) script.seed = *a.seed;

  const synth::SceneKind kind =
      a.scene.value_or(script.translates() ? synth::SceneKind::kBox : synth::SceneKind::kSphere);
  if (kind == synth::SceneKind::kSphere && script.translates()) {
    throw UsageError(motion_name + " translates the camera, which a sphere at infinity cannot "
                     "show; use --scene box");
  }
  const synth::Scene scene = synth::Scene::load(a.texture, kind);
  std::optional<Eigen::AlignedBox3d> region;
  if (kind == synth::SceneKind::kBox) region = scene.box.interior(script.wall_margin_m);
  const std::vector<StampedPose> poses = synth::generateTrajectory(script, region);

  const synth::Renderer renderer(scene, calibration, {a.output, a.supersample});
  synth::DegradeOptions degrade{.noise_sigma = a.noise,
                                .blur_sigma = a.blur,
                                .exposure_gain_std = a.exposure_gain,
                                .exposure_offset_std = a.exposure_offset,
                                .seed = script.seed,
                                .periodic_columns = a.output == synth::OutputKind::kPanorama};
  if (const auto problems = degrade.validate(); !problems.empty()) {
    throw UsageError(problems.front());
  }
  if (a.write_mask) {
    calibration.omni.mask = a.occluder->mask(calibration);
    calibration.omni.mask_file = "mask.png";
  }
  synth::DatasetWriter writer(a.out, calibration, a.jpeg);

  const auto start = std::chrono::steady_clock::now();
  tools::ProgressLine progress(stderr, static_cast<int>(poses.size()), "frames", !a.quiet);
  for (std::size_t k = 0; k < poses.size(); ++k) {
    cv::Mat image = renderer.render(poses[k].pose);
    if (a.occluder) a.occluder->paint(image, calibration);
    writer.addFrame(synth::degrade(image, degrade, k), poses[k]);
    progress.update(static_cast<int>(k + 1));
  }
  progress.finish();
  writer.finish();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  const cv::Size size = renderer.outputSize();
  std::printf("omnipose-synth: wrote %zu %s frames %dx%d (%s scene, %s, seed %llu) to %s "
              "in %.1f s (%.0f ms/frame)\n",
              poses.size(), synth::toString(a.output), size.width, size.height,
              synth::toString(kind), motion_name.c_str(),
              static_cast<unsigned long long>(script.seed), a.out.c_str(), seconds,
              1000.0 * seconds / poses.size());
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const Args args = parseArgs(argc, argv);
    if (args.help) {
      std::cout << kUsage;
      return 0;
    }
    if (!args.print_preset.empty()) {
      std::cout << synth::MotionScript::presetYaml(args.print_preset);
      return 0;
    }
    return run(args);
  } catch (const UsageError& e) {
    std::cerr << "omnipose-synth: " << e.what() << "\n(see omnipose-synth --help)\n";
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "omnipose-synth: error: " << e.what() << "\n";
    return 1;
  }
}
