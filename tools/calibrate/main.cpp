// omnipose-calibrate: lens calibration from omni images (GitHub issue 6). A thin main over
// omnipose_calibrate (src/calibrate): parses the options, loads the frames, writes the
// calibration YAML, the preview PNG and the report.
#include <algorithm>
#include <cctype>
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
#include <vector>

#include "omnipose/calibrate/checkerboard.hpp"
#include "omnipose/calibrate/lens_calibrator.hpp"
#include "omnipose/calibrate/mask_proposal.hpp"
#include "omnipose/calibrate/ocamcalib_import.hpp"
#include "omnipose/pipeline.hpp"
#include "omnipose/calibrate/preview.hpp"

namespace {

namespace fs = std::filesystem;
using omnipose::calibrate::LensCalibratorOptions;

void usage(std::FILE* out) {
  std::fprintf(
      out,
      "usage: omnipose-calibrate FRAMES... --out calibration.yaml [options]\n"
      "       omnipose-calibrate --propose-mask FRAMES... --out mask.png [--preview P.png]\n"
      "       omnipose-calibrate --checkerboard 9x6 --square 0.025 IMAGES... --out calibration.yaml\n"
      "       omnipose-calibrate --from-ocamcalib calib_results.txt --out calibration.yaml\n"
      "                          [FRAMES...] [--radius-inner R --radius-outer R] [--direction D]\n"
      "                          [--forward-angle DEG] [--width W --height H --horizon-row V]\n"
      "\n"
      "Finds the donut's centre and the used inner/outer radii (robust circle fits on the ring\n"
      "edges, median over the frames), proposes the panorama size and writes the calibration\n"
      "YAML (DESIGN.md section 6) with a note on how each value was determined, plus a preview.\n"
      "\n"
      "  FRAMES                  omni images, or directories of images (sorted by name)\n"
      "  --out FILE              calibration YAML to write (required)\n"
      "  --preview FILE          preview PNG (default: FILE of --out with _preview.png)\n"
      "Orientation:\n"
      "  --turn-left             the FRAMES, in this order, show the robot turning left in\n"
      "                          place (positive yaw): measures azimuth_direction\n"
      "  --up-cue bright|dark|none  vertical cue for outer_edge: the upward-looking side of the\n"
      "                          ring is brighter (sky, ceiling, lights; default) or darker\n"
      "  --default-outer-edge top|bottom  used when the cue is not decisive (default top:\n"
      "                          the paper's mounting, lens over the phone's front camera\n"
      "                          looking up at the mirror, so the outer ring looks up)\n"
      "  --forward-angle DEG     image angle atan2(y - cy, x - cx) of the robot's +x axis\n"
      "  --forward-point X,Y     an image point straight ahead of the robot (instead)\n"
      "Fix any value by hand:\n"
      "  --center X,Y  --radius-inner R  --radius-outer R   (used radii, no margin applied)\n"
      "  --margin PX             safety margin at both edges (default: 1 px + 2 x edge blur)\n"
      "  --direction cw|ccw  --outer-edge top|bottom\n"
      "  --width W  --height H  --horizon-row V  --horizon-radius R  --forward-column U\n"
      "  --radial-scale S        image px per radian of elevation at the horizon radius (from\n"
      "                          a lens model); default: the donut is taken as isotropic there\n"
      "Detection hints:\n"
      "  --center-guess X,Y  --inner-guess R  --outer-guess R   (pixels)\n"
      "Lens models:\n"
      "  --from-ocamcalib FILE   the lens is Scaramuzza's OCamCalib calib_results.txt: writes\n"
      "                          model ocamcalib (the file is copied beside --out), the ring from\n"
      "                          its ROI line (or --radius-inner/--radius-outer), a panorama\n"
      "                          inside the ring's elevations; FRAMES (optional) are previewed\n"
      "                          (and measure the direction with --turn-left)\n"
      "  --checkerboard COLSxROWS --square METRES   FRAMES are checkerboard views (COLSxROWS\n"
      "                          inner corners): calibrates the mei model with cv::omnidir,\n"
      "                          reports its reprojection error; ring given or detected\n"
      "Masks:\n"
      "  --propose-mask          FRAMES of the robot turning or driving: writes to --out an\n"
      "                          8-bit mask (0 = never use) of the textured pixels that stay\n"
      "                          still while the rest of the ring moves (mast, body, cables,\n"
      "                          bezel), and a preview; name it in calibration.yaml (omni.mask)\n"
      "Other:\n"
      "  --no-replay             skip the Pipeline replay of consecutive frames\n"
      "  --quiet                 print only errors\n"
      "Exit codes: 0 written, 1 calibration failed, 2 usage error.\n");
}

[[noreturn]] void usageError(const std::string& msg) {
  std::fprintf(stderr, "omnipose-calibrate: %s\n", msg.c_str());
  std::exit(2);
}

double parseNumber(const std::string& option, const std::string& text) {
  try {
    std::size_t pos = 0;
    const double v = std::stod(text, &pos);
    if (pos != text.size()) throw std::invalid_argument(text);
    return v;
  } catch (const std::exception&) {
    usageError(option + ": '" + text + "' is not a number");
  }
}

Eigen::Vector2d parsePoint(const std::string& option, const std::string& text) {
  const auto comma = text.find(',');
  if (comma == std::string::npos) usageError(option + ": expected X,Y, got '" + text + "'");
  return {parseNumber(option, text.substr(0, comma)), parseNumber(option, text.substr(comma + 1))};
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

}  // namespace

int main(int argc, char** argv) {
  LensCalibratorOptions options;
  std::vector<fs::path> inputs;
  fs::path out_yaml, preview, from_ocamcalib;
  std::string checkerboard;
  std::optional<double> square;
  bool quiet = false, propose_mask = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) usageError(arg + " needs a value");
      return argv[++i];
    };
    if (arg == "-h" || arg == "--help") {
      usage(stdout);
      return 0;
    } else if (arg == "--out") {
      out_yaml = value();
    } else if (arg == "--propose-mask") {
      propose_mask = true;
    } else if (arg == "--checkerboard") {
      checkerboard = value();
    } else if (arg == "--square") {
      square = parseNumber(arg, value());
    } else if (arg == "--from-ocamcalib") {
      from_ocamcalib = value();
    } else if (arg == "--preview") {
      preview = value();
    } else if (arg == "--turn-left") {
      options.turn_left = true;
    } else if (arg == "--up-cue") {
      try {
        options.up_cue = omnipose::calibrate::parseUpCue(value());
      } catch (const std::exception& e) {
        usageError(std::string("--up-cue: ") + e.what());
      }
    } else if (arg == "--default-outer-edge" || arg == "--outer-edge") {
      const std::string v = value();
      if (v != "top" && v != "bottom") usageError(arg + " must be top or bottom, not '" + v + "'");
      const auto e = v == "top" ? omnipose::OuterEdge::kTop : omnipose::OuterEdge::kBottom;
      if (arg == "--outer-edge") options.outer_edge = e;
      else options.default_outer_edge = e;
    } else if (arg == "--direction") {
      const std::string v = value();
      if (v != "cw" && v != "ccw") usageError("--direction must be cw or ccw, not '" + v + "'");
      options.direction = v == "cw" ? omnipose::AzimuthDirection::kCw : omnipose::AzimuthDirection::kCcw;
    } else if (arg == "--forward-angle") {
      options.forward_angle_deg = parseNumber(arg, value());
    } else if (arg == "--forward-point") {
      options.forward_point = parsePoint(arg, value());
    } else if (arg == "--center") {
      options.center = parsePoint(arg, value());
    } else if (arg == "--radius-inner") {
      options.radius_inner = parseNumber(arg, value());
    } else if (arg == "--radius-outer") {
      options.radius_outer = parseNumber(arg, value());
    } else if (arg == "--margin") {
      options.margin = parseNumber(arg, value());
    } else if (arg == "--width") {
      options.width = static_cast<int>(parseNumber(arg, value()));
    } else if (arg == "--height") {
      options.height = static_cast<int>(parseNumber(arg, value()));
    } else if (arg == "--horizon-row") {
      options.horizon_row = parseNumber(arg, value());
    } else if (arg == "--horizon-radius") {
      options.horizon_radius = parseNumber(arg, value());
    } else if (arg == "--radial-scale") {
      options.radial_scale = parseNumber(arg, value());
    } else if (arg == "--forward-column") {
      options.forward_column = parseNumber(arg, value());
    } else if (arg == "--center-guess") {
      options.detector.center_guess = parsePoint(arg, value());
    } else if (arg == "--inner-guess") {
      options.detector.inner_guess = parseNumber(arg, value());
    } else if (arg == "--outer-guess") {
      options.detector.outer_guess = parseNumber(arg, value());
    } else if (arg == "--no-replay") {
      options.replay = false;
    } else if (arg == "--quiet") {
      quiet = true;
    } else if (!arg.empty() && arg[0] == '-') {
      std::fprintf(stderr, "omnipose-calibrate: unknown option %s\n", arg.c_str());
      usage(stderr);
      return 2;
    } else {
      inputs.emplace_back(arg);
    }
  }
  if (inputs.empty() && from_ocamcalib.empty()) usageError("no FRAMES given (see --help)");
  if (out_yaml.empty()) usageError("--out FILE is required (see --help)");
  if (int(propose_mask) + int(!from_ocamcalib.empty()) + int(!checkerboard.empty()) > 1)
    usageError("--propose-mask, --from-ocamcalib and --checkerboard are separate steps: run them "
               "one by one");
  if (preview.empty()) {
    preview = out_yaml;
    preview.replace_filename(out_yaml.stem().string() + "_preview.png");
  }

  try {
    // Frames: files as given, directories expanded (sorted by name).
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
    std::vector<cv::Mat> frames;
    for (const auto& f : files) {
      cv::Mat m = cv::imread(f.string(), cv::IMREAD_COLOR);
      if (m.empty()) throw std::runtime_error(f.string() + ": cannot read image");
      frames.push_back(std::move(m));
    }
    if (propose_mask) return writeMaskProposal(frames, out_yaml, preview, quiet);
    if (!from_ocamcalib.empty()) {
      return writeModelCalibration(importOcamCalibFile(from_ocamcalib, options, frames, files),
                                   frames, out_yaml, preview, quiet);
    }
    if (!checkerboard.empty()) {
      omnipose::calibrate::CheckerboardOptions board;
      omnipose::calibrate::parsePatternSize(checkerboard, board);
      if (!square) usageError("--checkerboard needs --square METRES");
      board.square_m = *square;
      return writeModelCalibration(
          omnipose::calibrate::importCheckerboard(frames, board, modelImportOptions(options)),
          frames, out_yaml, preview, quiet);
    }
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
    const cv::Mat picture =
        omnipose::calibrate::renderPreview(frames, result.calibration, det, lines);
    if (!cv::imwrite(preview.string(), picture))
      throw std::runtime_error(preview.string() + ": cannot write preview");

    if (!quiet) {
      std::fputs(result.report().c_str(), stdout);
      std::printf("wrote %s and %s\n", out_yaml.c_str(), preview.c_str());
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "omnipose-calibrate: %s\n", e.what());
    return 1;
  }
}
