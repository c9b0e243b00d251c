// equirectFromOmni against the exact renderer: a texture rendered through a lens at the
// identity pose and resampled back is the texture again on the ring's elevations, in the
// same orientation (not mirrored, not turned), for the linear lens and a real mirror's
// OCamCalib polynomial; what the ring does not see is flat.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <opencv2/core.hpp>
#include <stdexcept>

#include "omnipose/synth/synth.hpp"

namespace omnipose::synth {
namespace {

constexpr double kPi = std::numbers::pi;
const std::filesystem::path kSourceDir = OMNIPOSE_SOURCE_DIR;

/// A smooth grey pattern of longitude and latitude that changes sign under a mirror
/// (lon -> -lon) and under a half turn, so a flipped or turned round trip cannot match.
double pattern(double lon, double lat) {
  return 128.0 + 50.0 * std::sin(3.0 * lon + 0.4) * std::cos(2.0 * lat) + 30.0 * std::sin(5.0 * lat + lon);
}

cv::Mat patternTexture(int width) {
  cv::Mat t(width / 2, width, CV_32FC1);
  for (int y = 0; y < t.rows; ++y) {
    for (int x = 0; x < t.cols; ++x) {
      const double lon = 2.0 * kPi * (0.5 - (x + 0.5) / t.cols);
      const double lat = kPi * (0.5 - (y + 0.5) / t.rows);
      t.at<float>(y, x) = static_cast<float>(pattern(lon, lat));
    }
  }
  return t;
}

Calibration ocamCalibration() {
  const std::string yaml =
      "omni:\n"
      "  model: ocamcalib\n"
      "  ocamcalib_file: steep_mirror_800_ocamcalib.txt\n"
      "  azimuth_zero_deg: 30.0\n"
      "  azimuth_direction: ccw\n"
      "panorama: {width: 1100, height: 110, horizon_row: 54.5, forward_column: 0.0}\n";
  return Calibration::parse(yaml, "steep.yaml", kSourceDir / "tests/data/catadioptric");
}

struct RoundTrip {
  double mean_abs_error = 0.0;  ///< grey levels, over the seen texels
  double max_abs_error = 0.0;
  double seen_fraction = 0.0;
  EquirectFromOmni result;
};

/// Renders the pattern through `cal` at the identity pose, resamples it back at `width`.
RoundTrip roundTrip(const Calibration& cal, int width) {
  Scene scene;
  scene.texture = patternTexture(4096);
  scene.kind = SceneKind::kSphere;
  RenderOptions options;
  options.supersample = 1;
  const Renderer renderer(scene, cal, options);
  cv::Mat omni;
  renderer.render(Eigen::Isometry3d::Identity()).convertTo(omni, CV_8U);
  RoundTrip r;
  r.result = equirectFromOmni(omni, cal, width);
  const cv::Mat& t = r.result.texture;
  double sum = 0.0;
  int n = 0;
  for (int y = 0; y < t.rows; ++y) {
    for (int x = 0; x < t.cols; ++x) {
      if (r.result.seen.at<std::uint8_t>(y, x) == 0) continue;
      const double lon = 2.0 * kPi * (0.5 - (x + 0.5) / t.cols);
      const double lat = kPi * (0.5 - (y + 0.5) / t.rows);
      const double e = std::abs(t.at<std::uint8_t>(y, x) - pattern(lon, lat));
      sum += e;
      r.max_abs_error = std::max(r.max_abs_error, e);
      ++n;
    }
  }
  r.mean_abs_error = n > 0 ? sum / n : 1e9;
  r.seen_fraction = static_cast<double>(n) / t.total();
  std::printf("round trip: %d seen texels, |error| mean %.3f, max %.1f grey levels\n", n,
              r.mean_abs_error, r.max_abs_error);
  return r;
}

/// Fraction of the texels of latitude row y that the ring saw.
double seenInRow(const EquirectFromOmni& e, int y) {
  return cv::countNonZero(e.seen.row(y)) / static_cast<double>(e.seen.cols);
}

void expectSeenBandMatchesTheRing(const EquirectFromOmni& e) {
  const int rows = e.seen.rows;
  const auto rowOf = [&](double lat) { return static_cast<int>(std::lround(rows * (0.5 - lat / kPi) - 0.5)); };
  const double margin = 3.0 * kPi / rows;  // three texels inside and outside the band
  EXPECT_EQ(seenInRow(e, rowOf(e.elevation_max - margin)), 1.0);
  EXPECT_EQ(seenInRow(e, rowOf(e.elevation_min + margin)), 1.0);
  EXPECT_EQ(seenInRow(e, rowOf(e.elevation_max + margin)), 0.0);
  EXPECT_EQ(seenInRow(e, rowOf(e.elevation_min - margin)), 0.0);
  // Unseen texels are flat at the seen texels' mean.
  EXPECT_NEAR(e.texture.at<std::uint8_t>(0, 0), e.fill, 0.5);
  EXPECT_NEAR(e.fill, cv::mean(e.texture, e.seen)[0], 0.5);
}

TEST(EquirectFromOmni, LinearLensRoundTripGivesTheTextureBack) {
  const Calibration cal;  // the default linear lens, 720 x 720
  const RoundTrip r = roundTrip(cal, 1024);
  const auto [e_in, e_out] = cal.ringElevations();
  EXPECT_NEAR(r.result.elevation_min, std::min(e_in, e_out), 1e-12);
  EXPECT_NEAR(r.result.elevation_max, std::max(e_in, e_out), 1e-12);
  // The rings' elevations span about 36 deg of 180: about a fifth of the texels.
  EXPECT_NEAR(r.seen_fraction, (r.result.elevation_max - r.result.elevation_min) / kPi, 0.01);
  // Two bilinear resamplings of a smooth pattern and two 8-bit roundings (mean 0.27, max 0.9).
  EXPECT_LT(r.mean_abs_error, 0.5);
  EXPECT_LT(r.max_abs_error, 2.0);
  expectSeenBandMatchesTheRing(r.result);
}

TEST(EquirectFromOmni, OcamCalibMirrorRoundTripGivesTheTextureBack) {
  const Calibration cal = ocamCalibration();
  const RoundTrip r = roundTrip(cal, 2048);
  EXPECT_GT(r.seen_fraction, 0.1);
  EXPECT_LT(r.mean_abs_error, 0.5);  // 0.27
  EXPECT_LT(r.max_abs_error, 2.0);   // 1.0
  expectSeenBandMatchesTheRing(r.result);
}

TEST(EquirectFromOmni, MirroredOrTurnedTextureWouldNotMatch) {
  // The pattern's own check: a flipped or half-turned texture is far from it, so the round
  // trips above prove the orientation.
  double flipped = 0.0, turned = 0.0;
  int n = 0;
  for (double lon = -3.0; lon < 3.0; lon += 0.1) {
    for (double lat = -0.3; lat < 0.3; lat += 0.05, ++n) {
      flipped += std::abs(pattern(-lon, lat) - pattern(lon, lat));
      turned += std::abs(pattern(lon + kPi, lat) - pattern(lon, lat));
    }
  }
  EXPECT_GT(flipped / n, 20.0);
  EXPECT_GT(turned / n, 20.0);
}

TEST(EquirectFromOmni, RejectsAWrongImageSizeAndABadWidth) {
  const Calibration cal;
  const cv::Mat small(100, 100, CV_8UC1, cv::Scalar(128));
  EXPECT_THROW(equirectFromOmni(small, cal, 1024), std::invalid_argument);
  const cv::Mat frame(cal.omni.image_height, cal.omni.image_width, CV_8UC1, cv::Scalar(128));
  EXPECT_THROW(equirectFromOmni(frame, cal, 1023), std::invalid_argument);
  EXPECT_THROW(equirectFromOmni(frame, cal, 8), std::invalid_argument);
  EXPECT_NO_THROW(equirectFromOmni(frame, cal, 64));
}

}  // namespace
}  // namespace omnipose::synth
