#include "omnipose/motion_fit.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>
#include <vector>

#include "omnipose/motion_model.hpp"

namespace omnipose {
namespace {

constexpr int kW = 1100, kWindow = 110, kStep = 20;
const double kGamma = 2 * std::numbers::pi / kW;

using Vec6 = Eigen::Matrix<double, 6, 1>;

/// Window motions the first-order model predicts for x, plus Gaussian noise (pixels /
/// radians) and a fraction of gross outliers.
std::vector<WindowMotion> synthesize(const Vec6& x, double noise_px, double outlier_fraction,
                                     std::mt19937& rng, double forward_column = 0.0) {
  const double kappa = windowAttenuation(kWindow, kGamma);
  std::normal_distribution<double> noise(0.0, 1.0);
  std::uniform_real_distribution<double> gross(-25.0, 25.0);
  std::bernoulli_distribution is_outlier(outlier_fraction);
  std::vector<WindowMotion> windows;
  for (int k = 0; k < kW / kStep; ++k) {
    WindowMotion w;
    w.center_u = k * kStep + kWindow / 2.0 - 0.5;
    const double theta = kGamma * (w.center_u - forward_column);
    const ModelMotion m = predictMotion(x, theta, kappa);
    w.du = m.du_rad / kGamma + noise_px * noise(rng);
    w.dv = m.dv_rad / kGamma + noise_px * noise(rng);
    w.rotation = m.rotation + 0.002 * noise(rng);
    w.scale = std::exp(m.log_scale + 0.003 * noise(rng));
    if (is_outlier(rng)) {
      w.du += gross(rng);
      w.dv += gross(rng);
      w.rotation += 0.1;
    }
    w.confidence = 0.5;
    w.rs_confidence = 0.5;
    w.valid = true;
    windows.push_back(w);
  }
  return windows;
}

MotionFit makeFit(bool use_rotation_scale = true) {
  MotionFit::Options o;
  o.use_rotation_scale = use_rotation_scale;
  return MotionFit(o, kGamma, kWindow);
}

TEST(MotionFit, RecoversEachSignOfTheModelExactlyWithoutNoise) {
  std::mt19937 rng(1);
  MotionFit fit = makeFit();
  for (int axis = 0; axis < 6; ++axis) {
    for (double sign : {-1.0, 1.0}) {
      Vec6 x = Vec6::Zero();
      x[axis] = sign * 0.05;
      const auto windows = synthesize(x, 0.0, 0.0, rng);
      const MotionEstimate e = fit.fit(windows, 0.0);
      ASSERT_EQ(e.status, FitStatus::kOk) << "axis " << axis;
      // The injected rotation/scale noise is the only error source here.
      EXPECT_LT((e.vector() - x).cwiseAbs().maxCoeff(), 2e-4) << "axis " << axis << "\n"
                                                              << e.vector().transpose();
    }
  }
}

TEST(MotionFit, RobustToNoiseAndTwentyPercentGrossOutliers) {
  std::mt19937 rng(42);
  MotionFit fit = makeFit();
  double worst = 0.0;
  for (int trial = 0; trial < 50; ++trial) {
    std::uniform_real_distribution<double> rot(-0.1, 0.1), tr(-0.05, 0.05);
    Vec6 x;
    x << rot(rng), rot(rng), rot(rng), tr(rng), tr(rng), tr(rng);
    const auto windows = synthesize(x, 0.1, 0.2, rng);
    const MotionEstimate e = fit.fit(windows, 0.0);
    ASSERT_NE(e.status, FitStatus::kLost);
    worst = std::max(worst, (e.vector() - x).cwiseAbs().maxCoeff());
    EXPECT_LT(e.windows_used, 55);  // outliers were rejected
  }
  // 0.1 px noise = 5.7e-4 rad per window; 55 windows: about 1e-4 rad per parameter.
  EXPECT_LT(worst, 6e-4) << "worst parameter error " << worst;
}

TEST(MotionFit, CovarianceMatchesTheActualScatter) {
  std::mt19937 rng(7);
  MotionFit fit = makeFit(false);
  Vec6 x;
  x << 0.02, -0.03, 0.04, 0.01, -0.02, 0.005;
  Vec6 sum_sq = Vec6::Zero(), predicted = Vec6::Zero();
  const int trials = 200;
  for (int t = 0; t < trials; ++t) {
    const MotionEstimate e = fit.fit(synthesize(x, 0.3, 0.0, rng), 0.0);
    sum_sq += (e.vector() - x).cwiseAbs2();
    predicted += e.covariance.diagonal();
  }
  for (int i = 0; i < 6; ++i) {
    const double ratio = std::sqrt(sum_sq[i] / predicted[i]);
    EXPECT_GT(ratio, 0.7) << i;
    EXPECT_LT(ratio, 1.4) << i;
  }
}

TEST(MotionFit, HonoursTheForwardColumn) {
  std::mt19937 rng(3);
  MotionFit fit = makeFit();
  Vec6 x;
  x << 0.03, 0.0, 0.0, 0.02, 0.0, 0.0;
  const auto windows = synthesize(x, 0.0, 0.0, rng, 275.0);
  EXPECT_LT((fit.fit(windows, 275.0).vector() - x).norm(), 5e-4);
  // Reading them with the wrong forward column turns roll into pitch.
  const MotionEstimate wrong = fit.fit(windows, 0.0);
  EXPECT_GT(std::abs(wrong.omega.y()), 0.02);
}

TEST(MotionFit, TooFewWindowsIsLostAndHalfTheCircleIsStillSolved) {
  std::mt19937 rng(5);
  MotionFit fit = makeFit();
  Vec6 x;
  x << 0.01, 0.02, 0.03, 0.0, 0.0, 0.0;
  auto windows = synthesize(x, 0.0, 0.0, rng);
  for (std::size_t k = 3; k < windows.size(); ++k) windows[k].valid = false;
  EXPECT_EQ(fit.fit(windows, 0.0).status, FitStatus::kLost);

  windows = synthesize(x, 0.0, 0.0, rng);
  for (std::size_t k = windows.size() / 2; k < windows.size(); ++k) windows[k].valid = false;
  const MotionEstimate half = fit.fit(windows, 0.0);
  EXPECT_EQ(half.status, FitStatus::kOk);  // 27 of 55 windows, above the 30 % threshold
  EXPECT_LT((half.vector() - x).cwiseAbs().maxCoeff(), 1e-3);
}

TEST(MotionFit, InvalidOptionsNameTheField) {
  MotionFit::Options o;
  o.median = 4;
  EXPECT_NE(o.validate().find("median"), std::string::npos);
  o = {};
  o.huber_delta_px = 0;
  EXPECT_THROW(MotionFit(o, kGamma, kWindow), std::invalid_argument);
}

TEST(MotionModel, WindowAttenuationIsBelowOneForWideWindows) {
  EXPECT_NEAR(windowAttenuation(1, kGamma), 1.0, 1e-12);
  const double k = windowAttenuation(kWindow, kGamma);
  EXPECT_LT(k, 1.0);
  EXPECT_GT(k, 0.99);
}

}  // namespace
}  // namespace omnipose
