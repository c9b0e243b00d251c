/// omnipose-synth: renders a synthetic dataset (DESIGN.md section 6) from an equirect photo,
/// with exact ground truth, through the exact renderer of omnipose::synth.

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <limits>
#include <optional>
#include <map>
#include <string>
#include <tuple>
#include <utility>

#include <opencv2/imgproc.hpp>

#include "omnipose/synth/synth.hpp"
#include "cli.hpp"
#include "progress_line.hpp"
#include "quiet_opencv.hpp"

namespace {

using namespace omnipose;

constexpr const char* kUsage = "usage: omnipose-synth --texture PHOTO.jpg --out DIR [options]";
constexpr const char* kDescription =
    "Renders a synthetic omni-camera dataset (calibration.yaml, frames/, timestamps.txt,\n"
    "groundtruth.tum; imu.csv with --gyro-rate) from an equirectangular photo, with exact\n"
    "ground truth.\n"
    "Exit codes: 0 written, 1 rendering or writing failed, 2 bad command line.";

/// A command-line mistake: reported with a hint to --help, exit code 2.
using tools::UsageError;

struct Args {
  std::string texture, out, motion, preset, print_preset, calibration;
  std::optional<synth::SceneKind> scene;
  synth::OutputKind output = synth::OutputKind::kOmni;
  std::optional<int> frames;
  std::optional<std::uint64_t> seed;
  double noise = 0.0, blur = 0.0, exposure_gain = 0.0, exposure_offset = 0.0;
  double readout = 0.0;  ///< rolling shutter readout, seconds (0 = global shutter)
  /// The motion between frames that rows and sub-exposures are rendered along.
  synth::Interpolation between_frames = synth::Interpolation::kSmooth;
  bool readout_given = false;  ///< else the calibration's sensor.readout_s
  double exposure_time = 0.0;  ///< motion blur: exposure time, seconds (0 = none)
  /// Auto-exposure: frame k exposed for exposure_times[k % size()] seconds, reported with it.
  std::vector<double> exposure_times;
  int exposure_samples = 0;    ///< sub-exposures, 0 = chosen from the motion
  double exposure_step = 0.0;  ///< auto-exposure step, relative (0 = none)
  int exposure_step_every = 0;
  int exposure_step_levels = synth::DegradeOptions{}.exposure_step_levels;
  double vignetting = 0.0;
  /// Walkers given on the command line (over the motion script's): --walkers text,
  /// --walker-distance, --walker-seed.
  std::optional<std::string> walkers;
  std::optional<std::pair<double, double>> walker_distance;
  std::optional<std::uint64_t> walker_seed;
  int jpeg = 0;
  int supersample = synth::RenderOptions{}.supersample;
  int texture_width = 0;  ///< 0: the photo's own resolution
  double texture_turn_deg = 0.0;  ///< synth::turnTexture()
  bool texture_mirror = false;
  std::optional<synth::Occluder> occluder;
  /// The gyro written to imu.csv (its calibration to calibration.yaml); none by default.
  std::optional<synth::GyroSimulation> gyro;
  bool write_mask = false;
  bool quiet = false;
};

/// The command line's options, bound to `a`; the values CLI11 cannot convert itself (scene,
/// output, occluder, the optional numbers) land in `raw` and are converted by finish().
struct Raw {
  std::string scene, output, occluder, walkers, walker_distance, gyro_rotation;
  synth::GyroSimulation gyro;
  int frames = 0;
  std::uint64_t seed = 0, walker_seed = 0;
};

/// "MIN[,MAX]" in metres (one number: MIN = MAX); throws std::invalid_argument.
std::pair<double, double> parseDistance(const std::string& text) {
  const auto comma = text.find(',');
  const auto number = [&](const std::string& field) {
    std::size_t end = 0;
    double v = 0.0;
    try {
      v = std::stod(field, &end);
    } catch (const std::exception&) {
      end = std::string::npos;
    }
    if (end != field.size() || !std::isfinite(v))
      throw std::invalid_argument("'" + text + "' is not MIN[,MAX] in metres");
    return v;
  };
  if (comma == std::string::npos) {
    const double d = number(text);
    return {d, d};
  }
  return {number(text.substr(0, comma)), number(text.substr(comma + 1))};
}

/// The scene, the motion, the output and the simple degradations.
void addSceneOptions(CLI::App& app, Args& a, Raw& raw) {
  app.add_option("--texture", a.texture, "equirectangular photo (2:1), converted to grey (required)")
      ->type_name("PHOTO");
  app.add_option("--texture-width", a.texture_width,
                 "resample the photo to W x W/2 first (area averaging when it shrinks): the "
                 "same scene at another resolution (default: as the photo is)")
      ->type_name("W");
  app.add_option("--texture-turn", a.texture_turn_deg,
                 "turn the photo about the vertical by DEG degrees (its columns rolled): "
                 "another room from the same photo (default 0)")
      ->type_name("DEG");
  app.add_flag("--texture-mirror", a.texture_mirror,
               "mirror the photo left to right (before --texture-turn): another room");
  app.add_option("--out", a.out, "dataset directory; DIR/frames must be empty or new (required)")
      ->type_name("DIR");
  app.add_option("--scene", raw.scene,
                 "texture at infinity, or on a 6 x 5 m box room (floor -1 m, ceiling +1.5 m); "
                 "default: box if the motion translates")
      ->type_name("sphere|box");
  app.add_option("--output", raw.output,
                 "donut image of the lens (default) or the unwrapped panorama")
      ->type_name("omni|panorama");
  app.add_option("--motion", a.motion,
                 "motion script (format: include/omnipose/synth/motion.hpp, example: "
                 "tools/synth/examples/tour.yaml)")
      ->type_name("MOTION.yaml");
  app.add_option("--preset", a.preset,
                 "built-in motion: roll, pitch, yaw, mixed, translate, demo (default: demo)")
      ->type_name("NAME");
  app.add_option("--print-preset", a.print_preset, "print a preset's motion script and exit")
      ->type_name("NAME");
  app.add_option("--frames", raw.frames, "total frame count (segments are cycled or cut to fit)")
      ->type_name("N");
  app.add_option("--seed", raw.seed,
                 "seed of the motion and the degradations (default: the script's; a vibration "
                 "keeps its own seed)")
      ->type_name("S");
  app.add_option("--noise", a.noise, "Gaussian sensor noise sigma, grey levels (default 0)")
      ->type_name("SIGMA");
  app.add_option("--blur", a.blur, "Gaussian blur sigma, pixels (default 0)")->type_name("SIGMA");
  app.add_option("--jpeg", a.jpeg, "write JPEG frames of quality Q (1..100); 0 = PNG (default)")
      ->type_name("Q");
  app.add_option("--exposure-jitter", a.exposure_gain,
                 "per-frame gain 1 + N(0, STD), e.g. 0.05 (default 0)")
      ->type_name("STD");
  app.add_option("--exposure-offset", a.exposure_offset,
                 "per-frame offset N(0, STD), grey levels (default 0)")
      ->type_name("STD");
  app.add_option("--calibration", a.calibration,
                 "lens and panorama; default: 720x720, centre 359.5, radii 120/300 px, "
                 "panorama 1100x110, horizon row 54.5")
      ->type_name("CAL.yaml");
}

/// The camera's shutter and exposure, the walkers, and the other degradations.
void addEffectOptions(CLI::App& app, Args& a, Raw& raw) {
  app.add_option("--readout", a.readout,
                 "rolling shutter: rows read out over S seconds, first to last (negative: last "
                 "to first), each row rendered from the pose at its own capture time along the "
                 "motion between frames; |S| at most one frame interval (default: the "
                 "calibration's sensor.readout_s, else 0: global shutter); the dataset's "
                 "calibration.yaml records it")
      ->type_name("S");
  app.add_option("--between-frames", a.between_frames,
                 "the motion between frames that rolling-shutter rows, motion blur and the gyro "
                 "see: smooth (velocity continuous through the frames' poses, as a vehicle's; "
                 "default), constant (constant velocity from one frame's pose to the next, the "
                 "velocity jumping at each frame) or spline (velocity and acceleration "
                 "continuous: a cubic B-spline with the script's poses as its control poses; "
                 "the frames' poses and groundtruth.tum are the spline's)")
      ->transform(CLI::CheckedTransformer(
          std::map<std::string, synth::Interpolation>{
              {"smooth", synth::Interpolation::kSmooth},
              {"constant", synth::Interpolation::kConstantVelocity},
              {"spline", synth::Interpolation::kSpline}},
          CLI::ignore_case))
      ->type_name("smooth|constant|spline");
  app.add_option("--exposure-time", a.exposure_time,
                 "motion blur: each row exposed for S seconds centred on its capture time (the "
                 "mean of sub-exposures along the motion between frames, and of the walkers' "
                 "motion); at most one frame interval (default 0: none)")
      ->type_name("S");
  app.add_option("--exposure-times", a.exposure_times,
                 "auto-exposure: frame k exposed for S_(k mod n) seconds, each written beside "
                 "its timestamp in timestamps.txt as a camera reports it (calibration.yaml "
                 "states none); each at most one frame interval; not with --exposure-time")
      ->delimiter(',')
      ->type_name("S1,S2,...");
  app.add_option("--exposure-samples", a.exposure_samples,
                 "sub-exposures of --exposure-time, 1..256 (default: enough that each moves "
                 "the image by at most 0.5 px, at most 64)")
      ->type_name("N");
  app.add_option("--walkers", raw.walkers,
                 "people walking circles around the robot, textured vertical cylinders "
                 "(defaults: 0.5 m wide, 1.7 m tall from the floor, 1.2 m/s, random "
                 "direction each); replaces these fields of the motion script's walkers")
      ->type_name("COUNT[,WIDTH_M,HEIGHT_M,SPEED_M_S]");
  app.add_option("--walker-distance", raw.walker_distance,
                 "radius of the walkers' circles about the room's centre, metres, drawn per "
                 "person (default 1.5,2.0); box scene: they must stay inside the room")
      ->type_name("MIN[,MAX]");
  app.add_option("--walker-seed", raw.walker_seed,
                 "seed of the walkers' draws (default: the motion script's walkers' seed, or 0)")
      ->type_name("S");
  app.add_option("--exposure-step", a.exposure_step,
                 "auto-exposure steps: every --exposure-step-every frames the gain is multiplied "
                 "or divided (random sign) by 1 + REL, e.g. 0.25, within "
                 "--exposure-step-levels steps of the start (default 0: none)")
      ->type_name("REL");
  app.add_option("--exposure-step-every", a.exposure_step_every,
                 "frames between auto-exposure steps (default 30 with --exposure-step)")
      ->type_name("N");
  app.add_option("--exposure-step-levels", a.exposure_step_levels,
                 "most auto-exposure steps away from the start gain, 1..16 (default 2)")
      ->type_name("L");
  app.add_option("--vignetting", a.vignetting,
                 "lens vignetting: omni pixels times max(0, 1 - STRENGTH (r / radius_outer)^2), "
                 "r the distance from the centre; panorama pixels the factor of the omni "
                 "pixel they unwrap from; STRENGTH in [0, 1] (default 0)")
      ->type_name("STRENGTH");
  app.add_option("--supersample", a.supersample, "K x K rays per pixel (default 3)")
      ->type_name("K");
  app.add_option("--occluder", raw.occluder,
                 "paint a static mast/cable occluder over a sector of the ring (image angle "
                 "and width, degrees; omni output), the same in every frame")
      ->type_name("ANGLE,WIDTH");
  app.add_flag("--write-mask", a.write_mask,
               "also write mask.png hiding the occluder (2 deg margin) and name it in "
               "calibration.yaml (omni.mask)");
  app.add_flag("--quiet", a.quiet, "no progress line (it is shown only on a terminal anyway)");
}

/// The gyro written beside the frames.
void addGyroOptions(CLI::App& app, Raw& raw) {
  const synth::GyroSimulation d;
  app.add_option("--gyro-rate", raw.gyro.rate_hz,
                 "write imu.csv: a gyro on the camera sampled at HZ measuring the rendered "
                 "motion's exact angular velocity (between frames as --between-frames), and "
                 "its calibration to calibration.yaml (section imu); default: no gyro")
      ->type_name("HZ");
  app.add_option("--gyro-noise", raw.gyro.noise_density,
                 "white rate noise density, rad/s/sqrt(Hz) (default " +
                     std::to_string(d.noise_density) + ")")
      ->type_name("D");
  app.add_option("--gyro-bias", raw.gyro.bias,
                 "length of the gyro's bias, rad/s, in a direction drawn from --seed (default " +
                     std::to_string(d.bias) + ")")
      ->type_name("B");
  app.add_option("--gyro-bias-walk", raw.gyro.bias_random_walk,
                 "bias random walk, rad/s^2/sqrt(Hz) (default 0)")
      ->type_name("W");
  app.add_option("--gyro-time-offset", raw.gyro.time_offset_s,
                 "a sample stamped t is taken at camera time t + S, seconds (default 0)")
      ->type_name("S");
  app.add_option("--gyro-rotation", raw.gyro_rotation,
                 "the IMU's mounting: camera from IMU as a unit quaternion (default 1,0,0,0)")
      ->type_name("W,X,Y,Z");
}

/// What the command line fills: the settings, and the text finish() converts.
struct CommandLine {
  Args args;
  Raw raw;
};

void addOptions(CLI::App& app, CommandLine& c) {
  addSceneOptions(app, c.args, c.raw);
  addEffectOptions(app, c.args, c.raw);
  addGyroOptions(app, c.raw);
}

/// "W,X,Y,Z": a quaternion; throws std::invalid_argument.
Eigen::Quaterniond parseQuaternion(const std::string& text) {
  std::array<double, 4> q{};
  std::size_t at = 0;
  for (std::size_t i = 0; i < q.size(); ++i) {
    const std::size_t comma = i + 1 < q.size() ? text.find(',', at) : text.size();
    std::size_t end = 0;
    const std::string field = comma == std::string::npos ? "" : text.substr(at, comma - at);
    try {
      q[i] = std::stod(field, &end);
    } catch (const std::exception&) {
      end = std::string::npos;
    }
    if (field.empty() || end != field.size() || !std::isfinite(q[i]))
      throw std::invalid_argument("'" + text + "' is not four numbers W,X,Y,Z");
    at = comma + 1;
  }
  return Eigen::Quaterniond(q[0], q[1], q[2], q[3]);
}

/// The gyro of the command line, when --gyro-rate is given; throws UsageError naming the
/// flag of a bad value or a --gyro-* option without --gyro-rate.
std::optional<synth::GyroSimulation> gyroOf(const CLI::App& app, const Raw& raw) {
  // Each field of GyroSimulation::validate()'s messages and its flag.
  static const std::map<std::string, std::string, std::less<>> kFlags = {
      {"gyro.rate_hz", "--gyro-rate"},         {"gyro.noise_density", "--gyro-noise"},
      {"gyro.bias", "--gyro-bias"},            {"gyro.bias_random_walk", "--gyro-bias-walk"},
      {"gyro.time_offset_s", "--gyro-time-offset"}, {"gyro.rotation", "--gyro-rotation"}};
  if (app.count("--gyro-rate") == 0) {
    for (const auto& [field, flag] : kFlags)
      if (app.count(flag) > 0) throw UsageError(flag + " needs --gyro-rate");
    return std::nullopt;
  }
  synth::GyroSimulation gyro = raw.gyro;
  if (app.count("--gyro-rotation") > 0) {
    try {
      gyro.rotation = parseQuaternion(raw.gyro_rotation);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--gyro-rotation: ") + e.what());
    }
  }
  // "gyro.rate_hz: ..." names the flag --gyro-rate, and so on.
  if (const auto problems = gyro.validate(); !problems.empty()) {
    const std::string& p = problems.front();
    const std::string field = p.substr(0, p.find(':'));
    const auto flag = kFlags.find(field);
    throw UsageError((flag != kFlags.end() ? flag->second : field) + p.substr(field.size()));
  }
  return gyro;
}

/// Converts what CLI11 left as text and checks what it cannot; throws UsageError.
void finish(const CLI::App& app, Args& a, const Raw& raw) {
  auto given = [&](const char* flag) { return app.count(flag) > 0; };
  auto convert = [](const char* flag, auto parse) {
    try {
      return parse();
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string(flag) + ": " + e.what());
    }
  };
  a.readout_given = given("--readout");
  if (given("--scene"))
    a.scene = convert("--scene", [&] { return synth::parseSceneKind(raw.scene); });
  if (given("--output"))
    a.output = convert("--output", [&] { return synth::parseOutputKind(raw.output); });
  if (given("--occluder"))
    a.occluder = convert("--occluder", [&] { return synth::parseOccluder(raw.occluder); });
  if (given("--frames")) a.frames = raw.frames;
  if (given("--seed")) a.seed = raw.seed;
  if (given("--walkers")) {
    convert("--walkers", [&] { return synth::parseWalkers(raw.walkers); });  // syntax, ranges
    a.walkers = raw.walkers;
  }
  if (given("--walker-distance"))
    a.walker_distance =
        convert("--walker-distance", [&] { return parseDistance(raw.walker_distance); });
  if (given("--walker-seed")) a.walker_seed = raw.walker_seed;
  a.gyro = gyroOf(app, raw);
  if (!a.print_preset.empty()) return;
  if (a.texture.empty()) throw UsageError("--texture is required");
  if (a.out.empty()) throw UsageError("--out is required");
  if (!a.motion.empty() && !a.preset.empty()) {
    throw UsageError("give --motion or --preset, not both");
  }
  if (given("--texture-width") && (a.texture_width < 16 || a.texture_width > 16384 || a.texture_width % 2 != 0))
    throw UsageError("--texture-width: must be an even number in [16, 16384]");
  if (!std::isfinite(a.texture_turn_deg)) throw UsageError("--texture-turn: must be finite");
  if (a.frames && *a.frames < 1) throw UsageError("--frames: must be >= 1");
  if (a.jpeg < 0 || a.jpeg > 100) throw UsageError("--jpeg: must be in [0, 100]");
  if (a.write_mask && !a.occluder) throw UsageError("--write-mask needs --occluder");
  if (a.occluder && a.output != synth::OutputKind::kOmni)
    throw UsageError("--occluder paints the omni image: it needs --output omni");
  if (!(a.exposure_time >= 0 && std::isfinite(a.exposure_time)))
    throw UsageError("--exposure-time: must be >= 0 seconds");
  for (const double e : a.exposure_times)
    if (!(e > 0 && std::isfinite(e))) throw UsageError("--exposure-times: each must be > 0 seconds");
  if (!a.exposure_times.empty() && a.exposure_time > 0.0)
    throw UsageError("--exposure-times and --exposure-time: give one of them");
  if (given("--exposure-samples")) {
    if (a.exposure_samples < 1 || a.exposure_samples > synth::kMaxExposureSamples)
      throw UsageError("--exposure-samples: must be in [1, " +
                       std::to_string(synth::kMaxExposureSamples) + "]");
    if (a.exposure_time == 0.0 && a.exposure_times.empty())
      throw UsageError("--exposure-samples needs --exposure-time or --exposure-times");
  }
  if (!(a.exposure_step >= 0 && a.exposure_step <= 1))
    throw UsageError("--exposure-step: must be in [0, 1]");
  if (given("--exposure-step-every")) {
    if (a.exposure_step_every < 1) throw UsageError("--exposure-step-every: must be >= 1");
    if (a.exposure_step == 0.0) throw UsageError("--exposure-step-every needs --exposure-step");
  } else if (a.exposure_step > 0.0) {
    a.exposure_step_every = 30;
  }
  if (a.exposure_step_levels < 1 || a.exposure_step_levels > 16)
    throw UsageError("--exposure-step-levels: must be in [1, 16]");
  if (given("--exposure-step-levels") && a.exposure_step == 0.0)
    throw UsageError("--exposure-step-levels needs --exposure-step");
  if (!(a.vignetting >= 0 && a.vignetting <= 1))
    throw UsageError("--vignetting: must be in [0, 1]");
}

/// The walkers of the run: the motion script's, with the command line's fields over them.
/// Throws UsageError naming the flag (or std::runtime_error naming the script) when they are
/// invalid or do not fit the scene.
std::optional<synth::Walkers> walkersOf(const Args& a, const synth::MotionScript& script,
                                        const std::string& motion_name, synth::SceneKind kind,
                                        const synth::Box& box) {
  const bool flags = a.walkers || a.walker_distance || a.walker_seed;
  if (!script.walkers && !a.walkers) {
    if (a.walker_distance) throw UsageError("--walker-distance needs --walkers");
    if (a.walker_seed) throw UsageError("--walker-seed needs --walkers");
    return std::nullopt;
  }
  synth::Walkers w = script.walkers.value_or(synth::Walkers{});
  if (a.walkers) {
    try {
      w = synth::parseWalkers(*a.walkers, w);
    } catch (const std::invalid_argument& e) {
      throw UsageError(std::string("--walkers: ") + e.what());
    }
  }
  if (a.walker_distance) std::tie(w.min_distance_m, w.max_distance_m) = *a.walker_distance;
  if (a.walker_seed) w.seed = *a.walker_seed;
  if (const auto problems = w.validate(kind, box); !problems.empty()) {
    if (flags) {
      const char* flag = a.walker_distance && problems.front().find("distance") != std::string::npos
                             ? "--walker-distance"
                             : "--walkers";
      throw UsageError(std::string(flag) + ": " + problems.front() + " (" + toString(kind) +
                       " scene)");
    }
    throw std::runtime_error(motion_name + ": " + problems.front() + " (" + toString(kind) +
                             " scene)");
  }
  return w;
}

/// Frame k's exposure, seconds (0: none).
double exposureOf(const Args& a, std::size_t k) {
  return a.exposure_times.empty() ? a.exposure_time : a.exposure_times[k % a.exposure_times.size()];
}

/// The longest exposure of any frame, seconds (0: none).
double longestExposure(const Args& a) {
  double most = a.exposure_time;
  for (const double e : a.exposure_times) most = std::max(most, e);
  return most;
}

/// The sub-exposure counts of the frames rendered (0 and 0 without rolling shutter or blur).
struct SampleRange {
  int fewest = 0, most = 0;
};

/// Renders, degrades and writes every frame, with a progress line: frame k at poses[k], its
/// rows and sub-exposures along the motion through `control` (the script's poses).
SampleRange renderFrames(const Args& a, const synth::Renderer& renderer,
                         const std::vector<StampedPose>& control,
                         const std::vector<StampedPose>& poses, double readout,
                         const synth::DegradeOptions& degrade, const cv::Mat& vignette,
                         const Calibration& calibration, synth::DatasetWriter& writer) {
  tools::ProgressLine progress(stderr, static_cast<int>(poses.size()), "frames", !a.quiet);
  SampleRange samples;
  for (std::size_t k = 0; k < poses.size(); ++k) {
    const double stamp = poses[k].timestamp;
    const auto pose_at = [&](double t) {
      return synth::poseAtTime(control, stamp + t, a.between_frames);
    };
    cv::Mat image;
    if (readout == 0.0 && longestExposure(a) == 0.0) {
      // Global shutter: the frame's own pose (and the walkers at its timestamp).
      image = renderer.walkers().empty() ? renderer.render(poses[k].pose)
                                         : renderer.render(poses[k].pose, stamp);
    } else {
      synth::FrameTiming timing{.timestamp_s = stamp,
                                .readout_s = readout,
                                .exposure_s = exposureOf(a, k),
                                .exposure_samples = a.exposure_samples};
      timing.exposure_samples = renderer.exposureSamples(pose_at, timing);
      samples.fewest = k == 0 ? timing.exposure_samples
                              : std::min(samples.fewest, timing.exposure_samples);
      samples.most = std::max(samples.most, timing.exposure_samples);
      image = renderer.render(pose_at, timing);
    }
    if (a.occluder) a.occluder->paint(image, calibration);
    if (!vignette.empty()) cv::multiply(image, vignette, image);
    writer.addFrame(synth::degrade(image, degrade, k), poses[k],
                    a.exposure_times.empty() ? std::numeric_limits<double>::quiet_NaN()
                                             : exposureOf(a, k));
    progress.update(static_cast<int>(k + 1));
  }
  progress.finish();
  writer.finish();
  return samples;
}

/// The frames' poses of a motion through `control` (the script's poses): those, or with
/// --between-frames spline the spline's at the frames' times.
std::vector<StampedPose> framePoses(const std::vector<StampedPose>& control,
                                    synth::Interpolation between_frames) {
  std::vector<StampedPose> poses = control;
  if (between_frames == synth::Interpolation::kSpline)
    for (StampedPose& p : poses) p.pose = synth::poseAtTime(control, p.timestamp, between_frames);
  return poses;
}

/// The gyro's samples over every row of every frame (the motion through `control`, the
/// script's poses), from kGyroMarginS before the first frame's earliest row to kGyroMarginS
/// after the last frame's latest.
GyroRecording gyroSamples(synth::GyroSimulation gyro, std::uint64_t seed,
                          const std::vector<StampedPose>& control, const Args& a, double readout) {
  constexpr double kGyroMarginS = 0.1;
  gyro.seed = seed;
  const double first = control.front().timestamp - 0.5 * longestExposure(a) - kGyroMarginS;
  const double last = control.back().timestamp + std::abs(readout) + 0.5 * longestExposure(a) +
                      kGyroMarginS;
  return synth::simulateGyro(control, a.between_frames, gyro, first, last);
}

/// The summary line's list of what the frames show beyond the motion (", vibration ...").
std::string effectsText(const Args& a, const synth::MotionScript& script, double readout,
                        const synth::Renderer& renderer, const synth::Scene& scene,
                        SampleRange samples) {
  std::string vibration;
  if (script.vibration) {
    char text[128];
    std::snprintf(text, sizeof(text), ", vibration %.2f deg at %.3g..%.3g Hz",
                  script.vibration->amplitude_deg, script.vibration->min_hz,
                  script.vibration->max_hz);
    vibration = text;
  }
  std::string shutter;
  if (readout != 0.0) {
    char text[96];
    std::snprintf(text, sizeof(text), ", rolling shutter %.4g s %s", std::abs(readout),
                  readout > 0.0 ? "first row first" : "last row first");
    shutter = text;
  }
  std::string effects;
  if (!a.exposure_times.empty()) {
    char text[128];
    std::snprintf(text, sizeof(text), ", exposures %zu cycled up to %.4g s in %d..%d sub-exposures",
                  a.exposure_times.size(), longestExposure(a), samples.fewest, samples.most);
    effects += text;
  } else if (a.exposure_time > 0.0) {
    char text[96];
    std::snprintf(text, sizeof(text), ", exposure %.4g s in %d..%d sub-exposures",
                  a.exposure_time, samples.fewest, samples.most);
    effects += text;
  }
  if (!renderer.walkers().empty()) {
    char text[96];
    std::snprintf(text, sizeof(text), ", %zu walkers at %.3g m/s", renderer.walkers().size(),
                  scene.walkers.speed_m_s);
    effects += text;
  }
  if (a.exposure_step > 0.0) {
    char text[96];
    std::snprintf(text, sizeof(text), ", exposure steps x%.3g every %d frames",
                  1.0 + a.exposure_step, a.exposure_step_every);
    effects += text;
  }
  if (a.vignetting > 0.0) {
    char text[64];
    std::snprintf(text, sizeof(text), ", vignetting %.3g", a.vignetting);
    effects += text;
  }
  if (a.gyro) {
    char text[96];
    std::snprintf(text, sizeof(text), ", gyro %.4g Hz in imu.csv", a.gyro->rate_hz);
    effects += text;
  }
  return vibration + shutter + effects;
}

int run(const Args& a) {
  Calibration calibration =
      a.calibration.empty() ? Calibration{} : Calibration::load(a.calibration);
  const std::string motion_name = !a.motion.empty() ? a.motion
                                  : !a.preset.empty() ? "preset " + a.preset
                                                      : "preset demo";
  synth::MotionScript script =
      !a.motion.empty() ? synth::MotionScript::load(a.motion, a.frames)
                        : synth::MotionScript::preset(a.preset.empty() ? "demo" : a.preset);
  if (a.frames) script.frames = *a.frames;
  if (a.seed) script.seed = *a.seed;
  // The rows are rendered with the readout and exposure the dataset's calibration then states.
  calibration.sensor.exposure_s = a.exposure_time;
  const double readout = a.readout_given ? a.readout : calibration.sensor.readout_s;
  calibration.sensor.readout_s = readout;
  if (!(std::abs(readout) <= 1.0 / script.frame_rate)) {
    throw UsageError(std::string(a.readout_given ? "--readout" : "sensor.readout_s of --calibration") +
                     ": |" + std::to_string(readout) +
                     "| s is longer than the frame interval of " + motion_name + " (" +
                     std::to_string(1.0 / script.frame_rate) + " s)");
  }
  if (!(longestExposure(a) <= 1.0 / script.frame_rate)) {
    throw UsageError((a.exposure_times.empty() ? "--exposure-time: " : "--exposure-times: ") +
                     std::to_string(longestExposure(a)) + " s is longer than the frame interval of " +
                     motion_name + " (" + std::to_string(1.0 / script.frame_rate) + " s)");
  }

  const synth::SceneKind kind =
      a.scene.value_or(script.translates() ? synth::SceneKind::kBox : synth::SceneKind::kSphere);
  if (kind == synth::SceneKind::kSphere && script.translates()) {
    throw UsageError(motion_name + " translates the camera, which a sphere at infinity cannot "
                     "show; use --scene box");
  }
  synth::Scene scene = synth::Scene::load(a.texture, kind);
  if (a.texture_width > 0) {
    cv::Mat resampled;
    cv::resize(scene.texture, resampled, cv::Size(a.texture_width, a.texture_width / 2), 0, 0,
               a.texture_width < scene.texture.cols ? cv::INTER_AREA : cv::INTER_LINEAR);
    scene.texture = resampled;
  }
  synth::turnTexture(scene, a.texture_turn_deg, a.texture_mirror);
  if (const auto walkers = walkersOf(a, script, motion_name, kind, scene.box)) {
    scene.walkers = *walkers;
  }
  std::optional<Eigen::AlignedBox3d> region;
  if (kind == synth::SceneKind::kBox) region = scene.box.interior(script.wall_margin_m);
  std::vector<StampedPose> poses;
  try {
    poses = synth::generateTrajectory(script, region);
  } catch (const std::invalid_argument& e) {  // e.g. --frames too few for the vibration's band
    throw std::runtime_error(motion_name + ": " + e.what());
  }
  const std::vector<StampedPose> control = std::exchange(poses, framePoses(poses, a.between_frames));

  const synth::Renderer renderer(scene, calibration, {a.output, a.supersample});
  synth::DegradeOptions degrade{.noise_sigma = a.noise,
                                .blur_sigma = a.blur,
                                .exposure_gain_std = a.exposure_gain,
                                .exposure_offset_std = a.exposure_offset,
                                .seed = script.seed,
                                .periodic_columns = a.output == synth::OutputKind::kPanorama,
                                .exposure_step = a.exposure_step,
                                .exposure_step_every = a.exposure_step_every,
                                .exposure_step_levels = a.exposure_step_levels};
  if (const auto problems = degrade.validate(); !problems.empty()) {
    throw UsageError(problems.front());
  }
  const cv::Mat vignette = a.vignetting > 0.0
                               ? synth::Vignetting{a.vignetting}.factors(calibration, a.output)
                               : cv::Mat();
  if (a.write_mask) {
    calibration.omni.mask = a.occluder->mask(calibration);
    calibration.omni.mask_file = "mask.png";
  }
  if (a.gyro) {
    calibration.imu = ImuCalibration{.rotation = a.gyro->rotation.normalized(),
                                     .time_offset_s = a.gyro->time_offset_s,
                                     .gyro_noise_density = a.gyro->noise_density > 0.0
                                                               ? std::optional(a.gyro->noise_density)
                                                               : std::nullopt};
  }
  synth::DatasetWriter writer(a.out, calibration, a.jpeg);
  if (a.gyro) writer.writeGyro(gyroSamples(*a.gyro, script.seed, control, a, readout).samples);

  const auto start = std::chrono::steady_clock::now();
  const SampleRange samples =
      renderFrames(a, renderer, control, poses, readout, degrade, vignette, calibration, writer);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  const cv::Size size = renderer.outputSize();
  const std::string effects = effectsText(a, script, readout, renderer, scene, samples);
  std::printf("omnipose-synth: wrote %zu %s frames %dx%d (%s scene, %s, seed %llu%s) to %s "
              "in %.1f s (%.0f ms/frame)\n",
              poses.size(), synth::toString(a.output), size.width, size.height,
              synth::toString(kind), motion_name.c_str(),
              static_cast<unsigned long long>(script.seed), effects.c_str(), a.out.c_str(), seconds,
              1000.0 * seconds / poses.size());
  return 0;
}

/// Prints a preset's script, or renders the dataset.
int generate(const tools::Cli& cli, CommandLine& c) {
  finish(cli.app(), c.args, c.raw);
  if (!c.args.print_preset.empty()) {
    std::cout << synth::MotionScript::presetYaml(c.args.print_preset);
    return 0;
  }
  return run(c.args);
}

}  // namespace

int main(int argc, char** argv) {
  omnipose::tools::quietOpenCvWarnings();
  return tools::runMain<CommandLine>(argc, argv, {"omnipose-synth", kUsage, kDescription},
                                     addOptions, generate);
}
