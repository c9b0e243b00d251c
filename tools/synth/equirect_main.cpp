/// omnipose-equirect: a real omni image and its calibration -> an equirectangular texture
/// for omnipose-synth (synth::equirectFromOmni), so a user's own camera, room and lens can
/// be rendered with exact ground truth.

#include <cstdio>
#include <iostream>
#include <numbers>
#include <string>

#include <opencv2/imgcodecs.hpp>

#include "omnipose/calibration.hpp"
#include "omnipose/image_decode.hpp"
#include "omnipose/synth/synth.hpp"
#include "cli.hpp"
#include "quiet_opencv.hpp"

namespace {

using namespace omnipose;

constexpr const char* kUsage =
    "usage: omnipose-equirect --omni IMAGE --calibration CAL.yaml --out TEXTURE.png [options]";
constexpr const char* kDescription =
    "Resamples a real omni image (the donut a camera under a mirror delivers) into an\n"
    "equirectangular grey texture for omnipose-synth --texture: every bearing the\n"
    "calibration's ring sees, at the identity pose; the elevations above and below the\n"
    "ring are filled flat with the mean grey level of the seen ones.\n"
    "Exit codes: 0 written, 1 reading, converting or writing failed, 2 bad command line.";

struct Args {
  std::string omni, calibration, out, seen;
  int width = 4096;
};

void addOptions(CLI::App& app, Args& a) {
  app.add_option("--omni", a.omni, "the omni image (PNG, JPEG, PNM or BMP), of the "
                 "calibration's frame size")->required();
  app.add_option("--calibration", a.calibration, "calibration.yaml of the camera that "
                 "took it (linear, ocamcalib or mei)")->required();
  app.add_option("--out", a.out, "the texture to write (8-bit grey; the format from the "
                 "extension)")->required();
  app.add_option("--width", a.width, "texture width, texels, even, 16..16384; the height "
                 "is half of it (default 4096)");
  app.add_option("--seen", a.seen, "also write a mask of the texels the ring saw (255) "
                 "and those filled (0)");
}

int run(const Args& a) {
  const Calibration calibration = Calibration::load(a.calibration);
  ImageLimits limits;
  limits.exact_size = cv::Size(calibration.omni.image_width, calibration.omni.image_height);
  const Expected<cv::Mat> image = readImage(a.omni, ImageColour::kGrey, limits);
  if (!image) throw std::runtime_error(std::string(image.error().message()));
  const synth::EquirectFromOmni e = synth::equirectFromOmni(*image, calibration, a.width);
  if (!cv::imwrite(a.out, e.texture)) throw std::runtime_error(a.out + ": cannot write the texture");
  if (!a.seen.empty() && !cv::imwrite(a.seen, e.seen)) {
    throw std::runtime_error(a.seen + ": cannot write the seen mask");
  }
  constexpr double kDeg = 180.0 / std::numbers::pi;
  std::printf("omnipose-equirect: wrote %s, %d x %d; the ring sees elevations %.1f..%.1f deg "
              "(%.0f %% of the texels), the rest filled with grey %.1f\n",
              a.out.c_str(), e.texture.cols, e.texture.rows, e.elevation_min * kDeg,
              e.elevation_max * kDeg, 100.0 * cv::countNonZero(e.seen) / e.seen.total(), e.fill);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  omnipose::tools::quietOpenCvWarnings();
  return tools::runMain<Args>(argc, argv, {"omnipose-equirect", kUsage, kDescription}, addOptions,
                              [](tools::Cli& cli, const Args& args) {
                                if (args.width < 16 || args.width > 16384 || args.width % 2 != 0) {
                                  return cli.usageError("--width " + std::to_string(args.width) +
                                                        " is not an even number in [16, 16384]");
                                }
                                return run(args);
                              });
}
