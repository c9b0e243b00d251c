/// Weighing each window's frequencies by their signal-to-noise ratio
/// (WindowRegistration::Options::noise_weighting): the noise measurement
/// (src/registration/noise_estimate.hpp) against noise of known sigma, and the shifts of
/// exactly shifted real photos with independent noise in both bands, with and without it.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "omnipose/window_registration.hpp"
#include "registration/noise_estimate.hpp"
#include "test_figures.hpp"
#include "test_images.hpp"

namespace omnipose {
namespace {

using registration::NoiseEstimator;

const cv::Size kPaperPanorama(1100, 110);

/// Smooth content: a ramp plus long waves, 30..220 grey levels.
cv::Mat smoothScene(cv::Size size) {
  cv::Mat image(size, CV_32FC1);
  for (int r = 0; r < size.height; ++r)
    for (int c = 0; c < size.width; ++c)
      image.at<float>(r, c) = static_cast<float>(
          120.0 + 0.6 * r + 60.0 * std::sin(2.0 * std::numbers::pi * c / 137.0) +
          30.0 * std::cos(2.0 * std::numbers::pi * (c + 2 * r) / 61.0));
  return image;
}

cv::Mat withNoise(const cv::Mat& image, double sigma, int seed) {
  cv::Mat noise(image.size(), CV_32FC1);
  cv::RNG rng(seed);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, sigma);
  return image + noise;
}

TEST(NoiseEstimator, MeasuresWhiteNoiseOnSmoothContent) {
  NoiseEstimator estimator(kPaperPanorama.width, 0, kPaperPanorama.height);
  EXPECT_EQ(estimator.blocks(), 550 * 55);
  for (const double sigma : {1.0, 3.0, 8.0}) {
    const double measured = estimator.sigma(withNoise(smoothScene(kPaperPanorama), sigma, 7));
    EXPECT_NEAR(measured, sigma, 0.04 * sigma) << "sigma " << sigma;
  }
  // Noise-free smooth content measures little (its curvature across a block).
  EXPECT_LT(estimator.sigma(smoothScene(kPaperPanorama)), 0.5);
}

TEST(NoiseEstimator, EdgesAndStructureInAFewBlocksBarelyCount) {
  NoiseEstimator estimator(kPaperPanorama.width, 0, kPaperPanorama.height);
  // Vertical (and horizontal) edges leave no diagonal detail at all, wherever they fall.
  cv::Mat edges = smoothScene(kPaperPanorama);
  for (int c = 0; c < edges.cols; ++c)
    if ((c / 5) % 2 == 1) edges.col(c) += 100.0f;
  const cv::Mat noise = withNoise(cv::Mat::zeros(kPaperPanorama, CV_32FC1), 3.0, 11);
  EXPECT_NEAR(estimator.sigma(edges + noise), estimator.sigma(smoothScene(kPaperPanorama) + noise),
              1e-4);
  // Diagonal structure (a 2 x 2 checker of 100 grey levels) in every tenth block: the median
  // moves to the 56th percentile of the noise's details, 13 % up.
  cv::Mat checkers = smoothScene(kPaperPanorama);
  int structured = 0;
  for (int r = 0; r + 1 < checkers.rows; r += 2)
    for (int c = 0; c + 1 < checkers.cols; c += 2)
      if ((r / 2 * 7 + c / 2 * 3) % 10 == 0) {
        checkers.at<float>(r, c) += 100.0f;
        checkers.at<float>(r + 1, c + 1) += 100.0f;
        ++structured;
      }
  EXPECT_NEAR(structured, estimator.blocks() / 10, estimator.blocks() / 100);
  const double measured = estimator.sigma(checkers + noise);
  EXPECT_GT(measured, 3.0);
  EXPECT_LT(measured, 3.0 * 1.2);
}

TEST(NoiseEstimator, OnlyUsableBlocksOfTheGivenRowsCount) {
  // Left half: sigma 3; right half: sigma 30 and masked out.
  cv::Mat image = withNoise(smoothScene(kPaperPanorama), 3.0, 3);
  const cv::Rect right(kPaperPanorama.width / 2, 0, kPaperPanorama.width / 2, kPaperPanorama.height);
  withNoise(smoothScene(kPaperPanorama), 30.0, 4)(right).copyTo(image(right));
  cv::Mat usable(kPaperPanorama, CV_32FC1, cv::Scalar(1.0));
  usable(right).setTo(0.0);
  NoiseEstimator masked(kPaperPanorama.width, 0, kPaperPanorama.height, usable);
  EXPECT_EQ(masked.blocks(), 275 * 55);
  EXPECT_NEAR(masked.sigma(image), 3.0, 0.15);
  NoiseEstimator unmasked(kPaperPanorama.width, 0, kPaperPanorama.height);
  EXPECT_GT(unmasked.sigma(image), 5.0);  // the median of the two halves' details
  // Rows outside [top, top + rows) are not read: noise there changes nothing.
  NoiseEstimator band(kPaperPanorama.width, 20, 40);
  cv::Mat rows = withNoise(smoothScene(kPaperPanorama), 3.0, 5);
  const double inside = band.sigma(rows);
  withNoise(smoothScene({kPaperPanorama.width, 20}), 50.0, 6).copyTo(rows.rowRange(0, 20));
  withNoise(smoothScene({kPaperPanorama.width, 50}), 50.0, 7).copyTo(rows.rowRange(60, 110));
  EXPECT_DOUBLE_EQ(band.sigma(rows), inside);
}

TEST(NoiseEstimator, NonFinitePixelsAreSkippedAndTooFewBlocksGiveNaN) {
  NoiseEstimator estimator(kPaperPanorama.width, 0, kPaperPanorama.height);
  cv::Mat image = withNoise(smoothScene(kPaperPanorama), 3.0, 8);
  image.colRange(0, 100).setTo(std::numeric_limits<float>::quiet_NaN());
  EXPECT_NEAR(estimator.sigma(image), 3.0, 0.15);
  image.setTo(std::numeric_limits<float>::quiet_NaN());
  EXPECT_TRUE(std::isnan(estimator.sigma(image)));
  NoiseEstimator tiny(16, 0, 16);  // 64 blocks: just enough
  EXPECT_EQ(tiny.blocks(), NoiseEstimator::kMinBlocks);
  EXPECT_FALSE(std::isnan(tiny.sigma(withNoise(smoothScene({16, 16}), 3.0, 9))));
  NoiseEstimator too_small(14, 0, 16);
  EXPECT_TRUE(std::isnan(too_small.sigma(withNoise(smoothScene({14, 16}), 3.0, 9))));
}

struct ShiftErrors {
  double rms_du = 0.0, rms_dv = 0.0;
  double median_du = 0.0, median_dv = 0.0;  ///< median |error|
  double rms_mean_du = 0.0;  ///< RMS over the pairs of the error of the windows' mean du
  double max_error = 0.0;  ///< largest |du error| or |dv error|
  double noise_sigma = 0.0;  ///< noiseSigma() after the last pair
  int windows = 0;
};

/// Every valid window of `pairs` pairs of `eq`'s horizon band shifted by
/// (0.1 (i mod 10), 0.07 (i mod 7)) pixels, noise `sigma` in both bands (seeded).
ShiftErrors shiftErrors(const cv::Mat& eq, double sigma, int pairs, bool noise_weighting) {
  const int centre = eq.rows / 2;
  WindowRegistration::Options options;
  options.noise_weighting = noise_weighting;
  WindowRegistration reg(kPaperPanorama, options);
  cv::RNG rng(31);
  cv::Mat noise(kPaperPanorama, CV_32FC1);
  std::vector<WindowMotion> out(reg.windowCount());
  ShiftErrors e;
  double sum_u = 0.0, sum_v = 0.0, sum_mean = 0.0;
  std::vector<double> abs_u, abs_v;
  for (int i = 0; i < pairs; ++i) {
    const double du = 0.1 * (i % 10), dv = 0.07 * (i % 7);
    cv::Mat ref = test::fourierShiftedBand(eq, centre, 110, 0.0, 0.0);
    cv::Mat cur = test::fourierShiftedBand(eq, centre, 110, -du, -dv);
    if (sigma > 0.0) {
      rng.fill(noise, cv::RNG::NORMAL, 0.0, sigma);
      ref += noise;
      rng.fill(noise, cv::RNG::NORMAL, 0.0, sigma);
      cur += noise;
    }
    reg.setReference(ref);
    EXPECT_TRUE(reg.measure(cur, out));
    double pair_sum = 0.0;
    int pair_count = 0;
    for (const WindowMotion& w : out) {
      if (!w.valid) continue;
      abs_u.push_back(std::abs(w.du - du));
      abs_v.push_back(std::abs(w.dv - dv));
      pair_sum += w.du - du;
      ++pair_count;
      sum_u += (w.du - du) * (w.du - du);
      sum_v += (w.dv - dv) * (w.dv - dv);
      e.max_error = std::max({e.max_error, std::abs(w.du - du), std::abs(w.dv - dv)});
      ++e.windows;
    }
    if (pair_count > 0) sum_mean += (pair_sum / pair_count) * (pair_sum / pair_count);
  }
  const auto median = [](std::vector<double>& v) {
    std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2), v.end());
    return v[v.size() / 2];
  };
  e.median_du = median(abs_u);
  e.median_dv = median(abs_v);
  e.rms_mean_du = std::sqrt(sum_mean / pairs);
  e.rms_du = std::sqrt(sum_u / e.windows);
  e.rms_dv = std::sqrt(sum_v / e.windows);
  e.noise_sigma = reg.noiseSigma();
  return e;
}

// The indoor photo (shelves, blinds, plain walls) with noise sigma 3 in both bands: the
// typical window's shift is nearer the truth with the weighting, in du and more so in dv
// (measured: median |error| 0.0135 -> 0.0125 px in du, 0.0149 -> 0.0128 in dv). Not the
// tails: the RMS over the windows and the error of their mean du (the yaw of a pure
// turn) stay within 10 % either way (0.0551 -> 0.0556, 0.0079 -> 0.0085 px).
TEST(NoiseWeighting, IndoorShiftsUnderNoiseAreMorePrecise) {
  const cv::Mat eq = test::loadEquirect(test::kIndoor, 1100);
  if (eq.empty()) GTEST_SKIP() << "shared test photo " << test::kIndoor << " not found";
  const ShiftErrors plain = shiftErrors(eq, 3.0, 20, false);
  const ShiftErrors weighted = shiftErrors(eq, 3.0, 20, true);
  testing::recordFigure("median_du_plain_px", plain.median_du, 4);
  testing::recordFigure("median_du_weighted_px", weighted.median_du, 4);
  testing::recordFigure("median_dv_plain_px", plain.median_dv, 4);
  testing::recordFigure("median_dv_weighted_px", weighted.median_dv, 4);
  testing::recordFigure("rms_du_plain_px", plain.rms_du, 4);
  testing::recordFigure("rms_du_weighted_px", weighted.rms_du, 4);
  testing::recordFigure("mean_du_plain_px", plain.rms_mean_du, 5);
  testing::recordFigure("mean_du_weighted_px", weighted.rms_mean_du, 5);
  testing::recordFigure("noise_sigma", weighted.noise_sigma, 3);
  ASSERT_GT(weighted.windows, 1000);
  EXPECT_GE(weighted.windows, plain.windows);
  EXPECT_LT(weighted.median_du, 0.97 * plain.median_du);
  EXPECT_LT(weighted.median_dv, 0.93 * plain.median_dv);
  EXPECT_LT(weighted.rms_du, 1.1 * plain.rms_du);
  EXPECT_LT(weighted.rms_dv, 1.1 * plain.rms_dv);
  EXPECT_LT(weighted.rms_mean_du, 1.15 * plain.rms_mean_du);
  // The noise measured on the last reference: the photo's own fine texture adds a little.
  EXPECT_NEAR(weighted.noise_sigma, 3.0, 0.6);
  EXPECT_TRUE(std::isnan(plain.noise_sigma));
}

// Without noise the weighting changes almost nothing: exact shifts stay as precise as the
// sub-pixel fit makes them (window_registration_test: every window within 0.04 px).
TEST(NoiseWeighting, NoiseFreeShiftsStayExact) {
  const cv::Mat eq = test::loadEquirect(test::kIndoor, 1100);
  if (eq.empty()) GTEST_SKIP() << "shared test photo " << test::kIndoor << " not found";
  const ShiftErrors plain = shiftErrors(eq, 0.0, 10, false);
  const ShiftErrors weighted = shiftErrors(eq, 0.0, 10, true);
  testing::recordFigure("max_error_plain_px", plain.max_error, 4);
  testing::recordFigure("max_error_weighted_px", weighted.max_error, 4);
  EXPECT_LT(weighted.max_error, 0.04);
  EXPECT_LT(weighted.rms_du, 1.2 * plain.rms_du + 0.001);
  EXPECT_LT(weighted.rms_dv, 1.2 * plain.rms_dv + 0.001);
}

}  // namespace
}  // namespace omnipose
