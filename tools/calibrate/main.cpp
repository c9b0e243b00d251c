// omnipose-calibrate: lens calibration from omni images, over omnipose_calibrate
// (src/calibrate): parses the options, loads the frames, writes the calibration YAML, the
// preview PNG and the report.
#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cstring>
#include <cstdlib>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <set>
#include <string>
#include <unistd.h>
#include <vector>

#include "cli.hpp"
#include "omnipose/calibrate/checkerboard.hpp"
#include "omnipose/calibrate/frame_selection.hpp"
#include "omnipose/calibrate/lens_calibrator.hpp"
#include "omnipose/calibrate/mask_proposal.hpp"
#include "omnipose/calibrate/ocamcalib_import.hpp"
#include "omnipose/image_decode.hpp"
#include "omnipose/pipeline.hpp"
#include "omnipose/calibrate/preview.hpp"
#include "omnipose/calibrate/imu_estimation.hpp"
#include "omnipose/calibrate/readout_estimation.hpp"
#include "omnipose/io/dataset.hpp"
#include "omnipose/io/gyro.hpp"
#include "quiet_opencv.hpp"

namespace {

namespace fs = std::filesystem;
using omnipose::calibrate::LensCalibratorOptions;

constexpr const char* kUsage =
    "usage: omnipose-calibrate FRAMES... --out calibration.yaml [options]\n"
    "       omnipose-calibrate --propose-mask FRAMES... --out mask.png [--preview P.png]\n"
    "       omnipose-calibrate --checkerboard 9x6 --square 0.025 IMAGES... --out calibration.yaml\n"
    "       omnipose-calibrate --readout-from DATASET --out calibration.yaml\n"
    "       omnipose-calibrate --imu-from DATASET --out calibration.yaml\n"
    "       omnipose-calibrate --from-ocamcalib calib_results.txt --out calibration.yaml\n"
    "                          [FRAMES...] [--radius-inner R --radius-outer R] [--direction D]\n"
    "                          [--forward-angle DEG] [--width W --height H --horizon-row V]";

constexpr const char* kDescription =
    "Finds the donut's centre and the used inner/outer radii (robust circle fits on the ring\n"
    "edges, median over the frames), proposes the panorama size and writes the calibration\n"
    "YAML (DESIGN.md section 6) with a note on how each value was determined, plus a preview.\n"
    "Lengths are in omni-image pixels, angles in degrees. Of many FRAMES (or checkerboard\n"
    "IMAGES) at most --max-frames are used, evenly spread over the sorted list; only those\n"
    "are read.\n"
    "Exit codes: 0 written, 1 calibration failed, 2 usage error.";

/// "X,Y" (pixels); a malformed value is a usage error naming `option`.
Eigen::Vector2d parsePoint(const std::string& option, const std::string& text) {
  const auto comma = text.find(',');
  auto number = [&](const std::string& part) {
    try {
      std::size_t pos = 0;
      const double v = std::stod(part, &pos);
      if (pos == part.size()) return v;
    } catch (const std::exception&) {
    }
    throw CLI::ValidationError(option, "'" + text + "' is not X,Y (two numbers)");
  };
  if (comma == std::string::npos) throw CLI::ValidationError(option, "expected X,Y, got '" + text + "'");
  return {number(text.substr(0, comma)), number(text.substr(comma + 1))};
}

/// --max-frames N: a whole number in [1, kMaxFramesLimit]; anything else names the flag.
std::size_t parseMaxFrames(const std::string& text) {
  const std::size_t limit = omnipose::calibrate::kMaxFramesLimit;
  const std::string expected = "must be a whole number from 1 to " + std::to_string(limit);
  long long v = 0;
  try {
    std::size_t pos = 0;
    v = std::stoll(text, &pos);
    if (pos != text.size()) throw std::invalid_argument(text);
  } catch (const std::exception&) {
    throw CLI::ValidationError("--max-frames", expected + ", not '" + text + "'");
  }
  if (v < 1 || v > static_cast<long long>(limit))
    throw CLI::ValidationError("--max-frames", expected + ", not " + text);
  return static_cast<std::size_t>(v);
}

/// An output file must be creatable before any work starts: its directory exists and is
/// writable, and the path is not a directory or a read-only file. Returns the problem
/// ("--out: a/b.yaml: directory a does not exist"), empty when writable. Creates nothing.
std::string outputProblem(const std::string& option, const fs::path& file) {
  const std::string what = option + ": " + file.string() + ": ";
  std::error_code ec;
  if (fs::is_directory(file, ec)) return what + "is a directory";
  const fs::path dir = file.parent_path().empty() ? fs::path(".") : file.parent_path();
  if (!fs::exists(dir, ec)) return what + "directory " + dir.string() + " does not exist";
  if (!fs::is_directory(dir, ec)) return what + dir.string() + " is not a directory";
  if (::access(dir.c_str(), W_OK | X_OK) != 0)
    return what + "cannot create files in " + dir.string() + " (" + std::strerror(errno) + ")";
  if (fs::exists(file, ec) && ::access(file.c_str(), W_OK) != 0)
    return what + "cannot overwrite it (" + std::strerror(errno) + ")";
  return {};
}

bool isImage(const fs::path& p) {
  std::string ext = p.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  static const std::set<std::string> kExt = {".png", ".jpg", ".jpeg", ".pgm", ".ppm", ".bmp", ".tif", ".tiff"};
  return kExt.contains(ext);
}

/// Quality gate: never write a calibration that omnipose-replay or omniposed would refuse
/// with the default pipeline (a panorama lower than the window, rows outside the ring ...).
void requirePipelineAccepts(const omnipose::Calibration& c) {
  try {
    omnipose::Pipeline pipeline(c, omnipose::PipelineOptions{});
  } catch (const std::invalid_argument& e) {
    throw std::runtime_error(std::string("refusing to write a calibration that omnipose-replay and "
                                         "omniposed would refuse: ") +
                             e.what() +
                             "\n  try: more or sharper frames, --outer-guess/--inner-guess, "
                             "--height >= 110 (the default window), or a lens model "
                             "(--from-ocamcalib)");
  }
}

/// --propose-mask: the mask of what stays still while the ring moves, and its preview.
int writeMaskProposal(const std::vector<cv::Mat>& frames, const fs::path& out,
                      const fs::path& preview, bool quiet) {
  const auto proposal = omnipose::calibrate::proposeMask(frames);
  if (!cv::imwrite(out.string(), proposal.mask))
    throw std::runtime_error(out.string() + ": cannot write the mask");
  if (!cv::imwrite(preview.string(), omnipose::calibrate::renderMaskPreview(frames, proposal.mask)))
    throw std::runtime_error(preview.string() + ": cannot write the preview");
  if (!quiet) {
    for (const auto& n : proposal.notes) std::printf("  %s\n", n.c_str());
    std::printf("wrote %s and %s; name it in calibration.yaml as omni.mask\n", out.c_str(),
                preview.c_str());
  }
  return 0;
}

/// --from-ocamcalib: the calibration of an OCamCalib lens, its preview when frames are given.
/// The choices left once a lens model is known, from the command line.
omnipose::calibrate::ModelImportOptions modelImportOptions(const LensCalibratorOptions& given) {
  omnipose::calibrate::ModelImportOptions o;
  o.radius_inner = given.radius_inner;
  o.radius_outer = given.radius_outer;
  o.direction = given.direction;
  o.turn_left = given.turn_left;
  o.forward_angle_deg = given.forward_angle_deg.value_or(0.0);
  o.width = given.width.value_or(o.width);
  o.height = given.height.value_or(o.height);
  o.horizon_row = given.horizon_row;
  return o;
}

/// --from-ocamcalib / --checkerboard: writes the model's calibration (after the quality
/// gate) and, when frames were given, its preview.
int writeModelCalibration(const omnipose::calibrate::ModelImport& result,
                          const std::vector<cv::Mat>& frames, const fs::path& out_yaml,
                          const fs::path& preview, bool quiet) {
  const omnipose::Calibration& c = result.calibration;
  requirePipelineAccepts(c);
  c.save(out_yaml);
  omnipose::Calibration::load(out_yaml);  // what we wrote must read back
  if (!frames.empty()) {
    const cv::Mat picture = omnipose::calibrate::renderPreview(frames, c, nullptr, result.notes);
    if (!cv::imwrite(preview.string(), picture))
      throw std::runtime_error(preview.string() + ": cannot write preview");
  }
  if (!quiet) {
    for (const auto& n : result.notes) std::printf("  %s\n", n.c_str());
    std::printf("wrote %s%s\n", out_yaml.c_str(),
                frames.empty() ? "" : (" and " + preview.string()).c_str());
  }
  return 0;
}

/// --from-ocamcalib: frames (optional) must have the file's frame size.
omnipose::calibrate::ModelImport importOcamCalibFile(const fs::path& file,
                                                    const LensCalibratorOptions& given,
                                                    const std::vector<cv::Mat>& frames,
                                                    const std::vector<fs::path>& files) {
  const auto model = omnipose::OcamCalibModel::load(file);
  for (std::size_t i = 0; i < frames.size(); ++i) {
    if (frames[i].cols != model.width || frames[i].rows != model.height)
      throw std::runtime_error(files[i].string() + ": " + std::to_string(frames[i].cols) + "x" +
                               std::to_string(frames[i].rows) + ", but " + file.string() +
                               " describes " + std::to_string(model.width) + "x" +
                               std::to_string(model.height) + " frames");
  }
  return omnipose::calibrate::importOcamCalib(file, modelImportOptions(given), frames);
}

/// The frames of a recording (--readout-from, --imu-from) with their timestamps and the
/// exposures recorded with them (NaN: none).
struct Recording {
  omnipose::Dataset dataset;
  std::vector<cv::Mat> frames;
  std::vector<double> times;
  std::vector<double> exposures;
};

/// Opens DATASET, which must have timestamps.txt (`what` is measured against the frame
/// times), and decodes the `max_frames` consecutive frames in its middle (the pairs must be
/// consecutive), no others; a frame that cannot be read is skipped and said.
Recording readRecording(const fs::path& dataset_dir, std::size_t max_frames, bool quiet,
                        const char* what) {
  Recording r{omnipose::Dataset::open(dataset_dir), {}, {}, {}};
  if (!r.dataset.timestamps_from_file)
    throw std::runtime_error((dataset_dir / "timestamps.txt").string() + ": missing; " + what +
                             " is measured against the frame times");
  for (const std::string& w : r.dataset.warnings) std::fprintf(stderr, "omnipose-calibrate: warning: %s\n", w.c_str());
  const omnipose::OdometryOptions defaults;
  const cv::Size size = omnipose::inputFrameSize(r.dataset.calibration, defaults.pipeline.unwrap.input);
  const std::size_t first = omnipose::calibrate::centredRunStart(r.dataset.frames.size(), max_frames);
  const std::size_t count = std::min(r.dataset.frames.size(), max_frames);
  if (!quiet && count < r.dataset.frames.size())
    std::printf("omnipose-calibrate: using frames %zu to %zu of %zu (--max-frames %zu consecutive "
                "ones in the middle)\n",
                first, first + count - 1, r.dataset.frames.size(), max_frames);
  r.frames.reserve(count);
  r.times.reserve(count);
  for (std::size_t k = first; k < first + count; ++k) {
    const omnipose::DatasetFrame& f = r.dataset.frames[k];
    auto image = omnipose::readFrame(f.path, size);
    if (!image) {
      if (!quiet) std::fprintf(stderr, "omnipose-calibrate: skipped %s\n", image.error().c_str());
      continue;
    }
    r.frames.push_back(std::move(*image));
    r.times.push_back(f.timestamp);
    r.exposures.push_back(f.exposure_s);
  }
  return r;
}

/// --readout-from DATASET: the rolling-shutter readout from a recording of the robot turning
/// in place at varying rates (readout_estimation.hpp); writes DATASET's calibration with
/// sensor.readout_s to `out_yaml`. Exit 0 written, 1 not measurable or unreadable.
int estimateReadoutOf(const fs::path& dataset_dir, const fs::path& out_yaml, std::size_t max_frames,
                      bool quiet) {
  const Recording r = readRecording(dataset_dir, max_frames, quiet, "the readout");
  if (!quiet)
    std::printf("omnipose-calibrate: %zu frames of %s, readouts tried from -0.05 to 0.05 s\n",
                r.frames.size(), dataset_dir.c_str());
  const omnipose::calibrate::ReadoutEstimate e =
      omnipose::calibrate::estimateReadout(r.dataset.calibration, r.frames, r.times);
  if (!quiet) {
    for (const auto& [readout, score] : e.curve) std::printf("  readout %+.4f s: score %.4g\n", readout, score);
  }
  if (!e.found) {
    std::fprintf(stderr, "omnipose-calibrate: %s\n", e.summary.c_str());
    return 1;
  }
  omnipose::Calibration c = r.dataset.calibration;
  c.sensor.readout_s = e.readout_s;
  c.save(out_yaml);
  if (!quiet) std::printf("omnipose-calibrate: %s; wrote %s\n", e.summary.c_str(), out_yaml.c_str());
  return 0;
}

/// --imu-from DATASET: the camera-gyro calibration (imu_estimation.hpp) from a recording of
/// the robot turning about changing axes with its gyro in DATASET/imu.csv; writes DATASET's
/// calibration with the imu section (its noise density kept) to `out_yaml` and prints the
/// gyro's bias. Exit 0 written, 1 not measurable or unreadable.
int estimateImuOf(const fs::path& dataset_dir, const fs::path& out_yaml, std::size_t max_frames,
                  bool quiet) {
  const Recording r = readRecording(dataset_dir, max_frames, quiet, "the gyro");
  if (!r.dataset.gyro_file)
    throw std::runtime_error((dataset_dir / "imu.csv").string() + ": missing; the gyro's recording is needed");
  const omnipose::GyroRecording gyro = omnipose::readGyroCsv(*r.dataset.gyro_file);
  const omnipose::calibrate::ImuSearchOptions options;
  if (!quiet)
    std::printf("omnipose-calibrate: %zu frames and %zu gyro samples (%.4g Hz) of %s, clock "
                "offsets tried from %+.3f to %+.3f s\n",
                r.frames.size(), gyro.samples.size(),
                gyro.median_interval_s > 0.0 ? 1.0 / gyro.median_interval_s : 0.0, dataset_dir.c_str(),
                -options.max_offset_s, options.max_offset_s);
  const omnipose::calibrate::ImuEstimate e = omnipose::calibrate::estimateImuCalibration(
      r.dataset.calibration, r.frames, r.times, gyro.samples, options, r.exposures);
  if (!e.found) {
    std::fprintf(stderr, "omnipose-calibrate: %s\n", e.summary.c_str());
    return 1;
  }
  omnipose::Calibration c = r.dataset.calibration;
  omnipose::ImuCalibration imu = e.imu;
  if (c.imu) imu.gyro_noise_density = c.imu->gyro_noise_density;
  c.imu = imu;
  if (e.readout_s != 0.0) c.sensor.readout_s = e.readout_s;
  c.save(out_yaml);
  if (!quiet) {
    const Eigen::Quaterniond& q = e.imu.rotation;
    std::printf("omnipose-calibrate: imu.rotation [%.6f, %.6f, %.6f, %.6f], imu.time_offset_s "
                "%+.6f, gyro bias (%+.6f, %+.6f, %+.6f) rad/s (not written: the pipeline tracks "
                "it)\n",
                q.w(), q.x(), q.y(), q.z(), e.imu.time_offset_s, e.bias.x(), e.bias.y(), e.bias.z());
    if (!e.pixels_summary.empty()) std::printf("omnipose-calibrate: %s\n", e.pixels_summary.c_str());
    std::printf("omnipose-calibrate: %s; wrote %s\n", e.summary.c_str(), out_yaml.c_str());
  }
  return 0;
}

/// The command line, as parsed.
struct Args {
  LensCalibratorOptions options;
  std::vector<std::string> inputs;
  std::string out, preview, ocamcalib, readout, imu, checkerboard;
  std::optional<double> square;
  bool quiet = false, propose_mask = false, no_replay = false;
  std::size_t max_frames = omnipose::calibrate::kDefaultMaxFrames;
};

/// A number into an optional (CLI11 converts it and names the flag when it cannot).
CLI::Option* addNumber(CLI::App& app, const char* flag, std::optional<double>& target,
                       const std::string& help) {
  return app.add_option_function<double>(flag, [&target](const double& v) { target = v; }, help);
}

/// As addNumber, truncated to an integer (any number is accepted).
CLI::Option* addInteger(CLI::App& app, const char* flag, std::optional<int>& target,
                        const std::string& help) {
  return app.add_option_function<double>(
      flag, [&target](const double& v) { target = static_cast<int>(v); }, help);
}

/// "X,Y" pixels into an optional.
CLI::Option* addPoint(CLI::App& app, const char* flag, std::optional<Eigen::Vector2d>& target,
                      const std::string& help) {
  return app
      .add_option_function<std::string>(
          flag, [&target, flag](const std::string& v) { target = parsePoint(flag, v); }, help)
      ->type_name("X,Y");
}

/// While it lives, the options added to `app` go to `group` in --help (CLI11's option
/// defaults); then the defaults' group is restored.
class HelpGroup {
 public:
  HelpGroup(CLI::App& app, const std::string& group)
      : app_(app), previous_(app.option_defaults()->get_group()) {
    app.option_defaults()->group(group);
  }
  ~HelpGroup() { app_.option_defaults()->group(previous_); }
  HelpGroup(const HelpGroup&) = delete;
  HelpGroup& operator=(const HelpGroup&) = delete;

 private:
  CLI::App& app_;
  std::string previous_;
};

omnipose::OuterEdge topOrBottom(const std::string& v) {
  return v == "top" ? omnipose::OuterEdge::kTop : omnipose::OuterEdge::kBottom;
}

void addOrientationOptions(CLI::App& app, LensCalibratorOptions& options) {
  const HelpGroup group(app, "Orientation");
  app.add_flag("--turn-left", options.turn_left,
               "the FRAMES, in this order, show the robot turning left in place (positive "
               "yaw): measures azimuth_direction");
  app.add_option_function<std::string>(
         "--up-cue",
         [&](const std::string& v) {
           try {
             options.up_cue = omnipose::calibrate::parseUpCue(v);
           } catch (const std::exception& e) {
             throw CLI::ValidationError("--up-cue", e.what());
           }
         },
         "vertical cue for outer_edge: the upward-looking side of the ring is brighter (sky, "
         "ceiling, lights; default) or darker")
      ->type_name("bright|dark|none");
  app.add_option_function<std::string>(
         "--default-outer-edge",
         [&](const std::string& v) { options.default_outer_edge = topOrBottom(v); },
         "used when the cue is not decisive (default top: the paper's mounting, lens over the "
         "phone's front camera looking up at the mirror, so the outer ring looks up)")
      ->type_name("top|bottom")
      ->check(omnipose::tools::oneOf({"top", "bottom"}));
  addNumber(app, "--forward-angle", options.forward_angle_deg,
            "image angle atan2(y - cy, x - cx) of the robot's +x axis, degrees")
      ->type_name("DEG");
  addPoint(app, "--forward-point", options.forward_point,
           "an image point straight ahead of the robot, pixels (instead of --forward-angle)");
}

void addByHandOptions(CLI::App& app, LensCalibratorOptions& options) {
  const HelpGroup group(app, "Fix any value by hand");
  addPoint(app, "--center", options.center, "centre of the donut, pixels");
  addNumber(app, "--radius-inner", options.radius_inner,
            "used inner radius, pixels (no margin applied)")
      ->type_name("R");
  addNumber(app, "--radius-outer", options.radius_outer,
            "used outer radius, pixels (no margin applied)")
      ->type_name("R");
  addNumber(app, "--margin", options.margin,
            "safety margin at both edges, pixels (default: 1 px + 2 x edge blur)")
      ->type_name("PX");
  app.add_option_function<std::string>(
         "--direction",
         [&](const std::string& v) {
           options.direction =
               v == "cw" ? omnipose::AzimuthDirection::kCw : omnipose::AzimuthDirection::kCcw;
         },
         "azimuth direction in the omni image")
      ->type_name("cw|ccw")
      ->check(omnipose::tools::oneOf({"cw", "ccw"}));
  app.add_option_function<std::string>(
         "--outer-edge", [&](const std::string& v) { options.outer_edge = topOrBottom(v); },
         "which panorama edge the outer ring becomes")
      ->type_name("top|bottom")
      ->check(omnipose::tools::oneOf({"top", "bottom"}));
  addInteger(app, "--width", options.width, "panorama width W, pixels")
      ->type_name("W");
  addInteger(app, "--height", options.height, "panorama height H, pixels")
      ->type_name("H");
  addNumber(app, "--horizon-row", options.horizon_row, "panorama row V of the horizon, pixels")
      ->type_name("V");
  addNumber(app, "--horizon-radius", options.horizon_radius,
            "omni-image radius R of the horizon, pixels")
      ->type_name("R");
  app.add_option_function<double>(
         "--forward-column", [&](const double& v) { options.forward_column = v; },
         "panorama column U of the robot's +x axis, pixels (default 0)")
      ->type_name("U");
  addNumber(app, "--radial-scale", options.radial_scale,
            "image px per radian of elevation at the horizon radius (from a lens model); "
            "default: the donut is taken as isotropic there")
      ->type_name("S");
}

void addHintOptions(CLI::App& app, LensCalibratorOptions& options) {
  const HelpGroup group(app, "Detection hints");
  addPoint(app, "--center-guess", options.detector.center_guess, "rough centre of the donut, pixels");
  addNumber(app, "--inner-guess", options.detector.inner_guess, "rough inner radius, pixels")
      ->type_name("R");
  addNumber(app, "--outer-guess", options.detector.outer_guess, "rough outer radius, pixels")
      ->type_name("R");
}

/// The lens-model, mask and other options (after the orientation, by-hand and hint groups).
void addModeOptions(CLI::App& app, Args& a) {
  const std::string models = "Lens models";
  app.add_option("--from-ocamcalib", a.ocamcalib,
                 "the lens is Scaramuzza's OCamCalib calib_results.txt: writes model ocamcalib "
                 "(the file is copied beside --out), the ring from its ROI line (or "
                 "--radius-inner/--radius-outer), a panorama inside the ring's elevations; "
                 "FRAMES (optional) are previewed (and measure the direction with --turn-left)")
      ->type_name("FILE")
      ->group(models);
  app.add_option("--checkerboard", a.checkerboard,
                 "FRAMES are checkerboard views (COLSxROWS inner corners): calibrates the mei "
                 "model with cv::omnidir, reports its reprojection error; ring given or detected")
      ->type_name("COLSxROWS")
      ->group(models);
  app.add_option_function<double>(
         "--square", [&a](const double& v) { a.square = v; },
         "checkerboard square size, metres (with --checkerboard)")
      ->type_name("METRES")
      ->group(models);

  app.add_flag("--propose-mask", a.propose_mask,
               "FRAMES of the robot turning or driving: writes to --out an 8-bit mask (0 = "
               "never use) of the textured pixels that stay still while the rest of the ring "
               "moves (mast, body, cables, bezel), and a preview; name it in calibration.yaml "
               "(omni.mask)")
      ->group("Masks");
  app.add_option_function<std::string>(
         "--max-frames", [&a](const std::string& v) { a.max_frames = parseMaxFrames(v); },
         "use at most N of the FRAMES (or checkerboard IMAGES), evenly spread over them in "
         "the given order (directories sorted by name), first and last included; with "
         "--readout-from or --imu-from, the N consecutive frames in the middle of the recording; "
         "only those "
         "are read (default " +
             std::to_string(omnipose::calibrate::kDefaultMaxFrames) + ", at most " +
             std::to_string(omnipose::calibrate::kMaxFramesLimit) + ")")
      ->type_name("N")
      ->group("Other");
  app.add_flag("--no-replay", a.no_replay, "skip the Pipeline replay of consecutive frames")
      ->group("Other");
  app.add_option("--readout-from", a.readout,
                 "DATASET (calibration.yaml, frames/, timestamps.txt) of the robot turning in "
                 "place, speeding up and slowing down: measures the rolling shutter's "
                 "sensor.readout_s and writes that calibration with it to --out")
      ->type_name("DATASET")
      ->group(models);
  app.add_option("--imu-from", a.imu,
                 "DATASET (calibration.yaml, frames/, timestamps.txt, imu.csv) of the robot "
                 "turning about changing axes, speeding up and slowing down: measures the "
                 "gyro's mounting (imu.rotation) and clock offset (imu.time_offset_s), prints "
                 "the gyro's bias, and writes that calibration with them to --out; with a "
                 "rolling shutter it also measures sensor.readout_s, starting from the "
                 "dataset's (within about 10 %: a datasheet's, or --readout-from's)")
      ->type_name("DATASET")
      ->group(models);
  app.add_flag("--quiet", a.quiet, "print only errors")->group("Other");
}

void addOptions(CLI::App& app, Args& a) {
  app.add_option("FRAMES", a.inputs, "omni images, or directories of images (sorted by name)");
  app.add_option("--out", a.out, "calibration YAML (or mask PNG) to write (required)")
      ->type_name("FILE");
  app.add_option("--preview", a.preview, "preview PNG (default: FILE of --out with _preview.png)")
      ->type_name("FILE");
  addOrientationOptions(app, a.options);
  addByHandOptions(app, a.options);
  addHintOptions(app, a.options);
  addModeOptions(app, a);
}

/// --readout-from and --imu-from: the usage checks, then estimateReadoutOf() or
/// estimateImuOf().
int runRecording(const omnipose::tools::Cli& cli, const Args& a) {
  const char* mode = a.readout.empty() ? "--imu-from" : "--readout-from";
  if (!a.readout.empty() && !a.imu.empty())
    return cli.usageError("give --readout-from or --imu-from, not both");
  if (a.out.empty()) return cli.usageError("--out FILE is required");
  if (!a.inputs.empty() || !a.ocamcalib.empty() || !a.checkerboard.empty() || a.propose_mask)
    return cli.usageError(std::string(mode) + " takes no FRAMES and no other mode");
  if (const auto problem = outputProblem("--out", a.out); !problem.empty())
    return cli.usageError(problem);
  return a.readout.empty() ? estimateImuOf(a.imu, a.out, a.max_frames, a.quiet)
                           : estimateReadoutOf(a.readout, a.out, a.max_frames, a.quiet);
}

/// Frames: files as given, directories expanded (sorted by name).
std::vector<fs::path> expandInputs(const std::vector<fs::path>& inputs) {
  std::vector<fs::path> files;
  for (const auto& in : inputs) {
    if (fs::is_directory(in)) {
      std::vector<fs::path> dir;
      for (const auto& e : fs::directory_iterator(in))
        if (e.is_regular_file() && isImage(e.path())) dir.push_back(e.path());
      std::sort(dir.begin(), dir.end());
      if (dir.empty()) throw std::runtime_error(in.string() + ": no images in this directory");
      files.insert(files.end(), dir.begin(), dir.end());
    } else if (fs::exists(in)) {
      files.push_back(in);
    } else {
      throw std::runtime_error(in.string() + ": no such file or directory");
    }
  }
  return files;
}

/// At most `max_frames` of `files`, evenly spread; only those are decoded. A frame that
/// cannot be read is named and skipped; `files` becomes the list of the frames returned.
std::vector<cv::Mat> readSelectedFrames(std::vector<fs::path>& files, std::size_t max_frames,
                                        bool quiet) {
  std::vector<cv::Mat> frames;
  if (files.empty()) return frames;
  const auto chosen = omnipose::calibrate::selectEvenly(files.size(), max_frames);
  if (!quiet)
    std::fprintf(stderr, "omnipose-calibrate: %s\n",
                 omnipose::calibrate::selectionMessage(files.size(), chosen.size()).c_str());
  std::vector<fs::path> used;
  std::size_t unreadable = 0;
  for (const std::size_t i : chosen) {
    omnipose::ImageLimits limits;
    limits.apply_exif_orientation = true;  // photos of the lens, as a viewer shows them
    omnipose::Expected<cv::Mat> m = omnipose::readImage(files[i], omnipose::ImageColour::kBgr, limits);
    if (!m) {
      std::fprintf(stderr, "omnipose-calibrate: %s, skipped\n", m.error().c_str());
      ++unreadable;
      continue;
    }
    frames.push_back(std::move(*m));
    used.push_back(files[i]);
  }
  if (frames.empty())
    throw std::runtime_error(chosen.size() == 1
                                 ? files[chosen.front()].string() + ": cannot read image"
                                 : "none of the " + std::to_string(chosen.size()) +
                                       " frames selected could be read as an image");
  if (unreadable > 0 && !quiet)
    std::fprintf(stderr, "omnipose-calibrate: %zu of %zu selected frames could not be read; "
                 "using the other %zu\n", unreadable, chosen.size(), frames.size());
  files = std::move(used);
  return frames;
}

/// The default mode: measures the lens from the frames, writes the calibration (after the
/// quality gate, read back), the preview and the report.
int writeLensCalibration(const std::vector<cv::Mat>& frames, const LensCalibratorOptions& options,
                         const fs::path& out_yaml, const fs::path& preview, bool quiet) {
  if (!quiet) std::printf("omnipose-calibrate: %zu frame(s), %dx%d\n", frames.size(),
                          frames.front().cols, frames.front().rows);
  const auto result = omnipose::calibrate::calibrateLens(frames, options);
  requirePipelineAccepts(result.calibration);
  {
    std::ofstream out(out_yaml);
    if (!out) throw std::runtime_error(out_yaml.string() + ": cannot write");
    out << result.yaml();
    if (!out) throw std::runtime_error(out_yaml.string() + ": write failed");
  }
  // Read it back: what we wrote must be a valid calibration.
  omnipose::Calibration::load(out_yaml);

  const auto lines = result.summaryLines();
  const omnipose::calibrate::RingDetection* det = nullptr;
  if (!result.detection_errors.empty() && result.detection_errors.front().empty())
    det = &result.detections.front();
  const cv::Mat picture = omnipose::calibrate::renderPreview(frames, result.calibration, det, lines);
  if (!cv::imwrite(preview.string(), picture))
    throw std::runtime_error(preview.string() + ": cannot write preview");
  if (!quiet) {
    std::fputs(result.report().c_str(), stdout);
    std::printf("wrote %s and %s\n", out_yaml.c_str(), preview.c_str());
  }
  return 0;
}

/// Every mode but --readout-from and --imu-from: the usage checks (every file written is checked before a
/// frame is read), then the frames, then the mode's work.
int runOnFrames(const omnipose::tools::Cli& cli, Args& a) {
  if (a.no_replay) a.options.replay = false;
  const std::vector<fs::path> inputs(a.inputs.begin(), a.inputs.end());
  const fs::path out_yaml = a.out, from_ocamcalib = a.ocamcalib;
  fs::path preview = a.preview;
  if (inputs.empty() && from_ocamcalib.empty()) return cli.usageError("no FRAMES given");
  if (out_yaml.empty()) return cli.usageError("--out FILE is required");
  if (int(a.propose_mask) + int(!from_ocamcalib.empty()) + int(!a.checkerboard.empty()) > 1)
    return cli.usageError("--propose-mask, --from-ocamcalib and --checkerboard are separate "
                          "steps: run them one by one");
  const bool preview_given = !preview.empty();
  if (!preview_given) {
    preview = out_yaml;
    preview.replace_filename(out_yaml.stem().string() + "_preview.png");
  }
  omnipose::calibrate::CheckerboardOptions board;
  if (!a.checkerboard.empty()) {
    try {
      omnipose::calibrate::parsePatternSize(a.checkerboard, board);
    } catch (const std::exception& e) {
      return cli.usageError(std::string("--checkerboard: ") + e.what());
    }
    if (!a.square) return cli.usageError("--checkerboard needs --square METRES");
    board.square_m = *a.square;
  }
  // --out (the OCamCalib file is copied into its directory) and the preview, written
  // whenever frames are given.
  if (const auto problem = outputProblem("--out", out_yaml); !problem.empty())
    return cli.usageError(problem);
  if (!inputs.empty())
    if (const auto problem = outputProblem(
            preview_given ? "--preview" : "--preview (default, beside --out)", preview);
        !problem.empty())
      return cli.usageError(problem);

  std::vector<fs::path> files = expandInputs(inputs);
  const std::vector<cv::Mat> frames = readSelectedFrames(files, a.max_frames, a.quiet);
  if (a.propose_mask) return writeMaskProposal(frames, out_yaml, preview, a.quiet);
  if (!from_ocamcalib.empty())
    return writeModelCalibration(importOcamCalibFile(from_ocamcalib, a.options, frames, files),
                                 frames, out_yaml, preview, a.quiet);
  if (!a.checkerboard.empty())
    return writeModelCalibration(
        omnipose::calibrate::importCheckerboard(frames, board, modelImportOptions(a.options)),
        frames, out_yaml, preview, a.quiet);
  return writeLensCalibration(frames, a.options, out_yaml, preview, a.quiet);
}

}  // namespace

int main(int argc, char** argv) {
  omnipose::tools::quietOpenCvWarnings();
  return omnipose::tools::runMain<Args>(
      argc, argv, {"omnipose-calibrate", kUsage, kDescription}, addOptions,
      [](omnipose::tools::Cli& cli, Args& args) {
        return args.readout.empty() && args.imu.empty() ? runOnFrames(cli, args)
                                                        : runRecording(cli, args);
      });
}
