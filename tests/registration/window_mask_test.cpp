/// Static masks in the window registration: a textured occluder that stays still
/// while the scene shifts pulls the windows it covers towards zero shift; with its mask the
/// shift comes back, and windows mostly masked are not measured.

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>
#include <vector>

#include "omnipose/window_registration.hpp"
#include "test_figures.hpp"
#include "test_images.hpp"

namespace omnipose {
namespace {

constexpr int kW = 1100, kH = 110;

/// A static "mast" over columns [first, first + width): textured, identical in every frame.
void paintMast(cv::Mat& panorama, int first, int width) {
  cv::RNG rng(7);
  for (int v = 0; v < kH; ++v)
    for (int u = first; u < first + width; ++u)
      panorama.at<float>(v, u % kW) = static_cast<float>(90 + 50 * std::sin(v * 0.4) +
                                                         40 * ((u / 6) % 2) + rng.uniform(-10, 10));
}

struct Pair {
  cv::Mat previous, current;
};

/// The indoor horizon band and a copy shifted by (du, dv) px (exact Fourier shift), both
/// with the same static mast over columns [300, 360).
Pair mastPair(double du, double dv) {
  const cv::Mat eq = test::loadEquirect(test::kIndoor, kW);
  if (eq.empty()) return {};
  Pair p{test::fourierShiftedBand(eq, eq.rows / 2, kH, 0.0, 0.0),
         test::fourierShiftedBand(eq, eq.rows / 2, kH, du, dv)};
  paintMast(p.previous, 300, 60);
  paintMast(p.current, 300, 60);
  return p;
}

/// Largest shift error over the windows that overlap the mast but are still measured.
/// The current band's content moved by (du, dv), so it appears at -(du, dv) in the previous
/// one: that is what a window measures (window_registration.hpp).
double worstErrorNearMast(const std::vector<WindowMotion>& m, const WindowRegistration& reg,
                          double du, double dv) {
  double worst = 0.0;
  for (int k = 0; k < reg.windowCount(); ++k) {
    const int first = (k * 20) % kW;
    const bool overlaps = first < 360 && first + 110 > 300;
    if (!overlaps || !m[k].valid) continue;
    worst = std::max(worst, std::hypot(m[k].du + du, m[k].dv + dv));
  }
  return worst;
}

TEST(WindowMask, MaskedMastNoLongerPullsTheShiftToZero) {
  const double du = 1.7, dv = -0.6;
  const Pair p = mastPair(du, dv);
  if (p.previous.empty()) GTEST_SKIP() << "indoor photo not found";

  WindowRegistration plain(cv::Size(kW, kH), WindowRegistration::Options{});
  std::vector<WindowMotion> m(plain.windowCount());
  plain.setReference(p.previous);
  ASSERT_TRUE(plain.measure(p.current, m));
  const double unmasked = worstErrorNearMast(m, plain, du, dv);

  cv::Mat validity(kH, kW, CV_32FC1, cv::Scalar(1.0f));
  validity.colRange(300, 360).setTo(0.0f);
  WindowRegistration masked(cv::Size(kW, kH), WindowRegistration::Options{});
  masked.setValidity(validity);
  masked.setReference(p.previous);
  ASSERT_TRUE(masked.measure(p.current, m));
  const double with_mask = worstErrorNearMast(m, masked, du, dv);
  testing::recordFigure("worst_mast_window_shift_error_unmasked_px", unmasked, 3);
  testing::recordFigure("worst_mast_window_shift_error_masked_px", with_mask, 3);
  EXPECT_GT(unmasked, 0.3) << "the static mast should pull the unmasked windows";
  EXPECT_LT(with_mask, 0.05) << "worst shift error of the masked windows over the mast, px";

  // Windows mostly over the mast (60 of 110 columns near the taper's peak) are dropped.
  EXPECT_GE(masked.maskedWindowCount(), 1);
  int flagged = 0;
  for (const auto& w : m) {
    if (w.masked) {
      ++flagged;
      EXPECT_FALSE(w.valid);
    }
  }
  EXPECT_EQ(flagged, masked.maskedWindowCount());
}

TEST(WindowMask, AllOnesMapIsThePlainTaperBitForBit) {
  const Pair p = mastPair(0.8, 0.3);
  if (p.previous.empty()) GTEST_SKIP() << "indoor photo not found";
  const cv::Size panorama(kW, kH);
  WindowRegistration a(panorama, WindowRegistration::Options{});
  WindowRegistration b(panorama, WindowRegistration::Options{});
  b.setValidity(cv::Mat(kH, kW, CV_32FC1, cv::Scalar(1.0f)));
  std::vector<WindowMotion> ma(a.windowCount()), mb(b.windowCount());
  a.setReference(p.previous);
  b.setReference(p.previous);
  ASSERT_TRUE(a.measure(p.current, ma));
  ASSERT_TRUE(b.measure(p.current, mb));
  for (int k = 0; k < a.windowCount(); ++k) {
    EXPECT_EQ(ma[k].du, mb[k].du);
    EXPECT_EQ(ma[k].dv, mb[k].dv);
  }
  EXPECT_EQ(b.maskedWindowCount(), 0);
}

TEST(WindowMask, WrongSizedMapIsRefused) {
  WindowRegistration reg(cv::Size(kW, kH), WindowRegistration::Options{});
  EXPECT_THROW(reg.setValidity(cv::Mat(10, 10, CV_32FC1, cv::Scalar(1.0f))), std::invalid_argument);
  EXPECT_THROW(reg.setValidity(cv::Mat(kH, kW, CV_8UC1, cv::Scalar(1))), std::invalid_argument);
}

}  // namespace
}  // namespace omnipose
