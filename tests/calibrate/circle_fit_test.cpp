// Circle fits of the calibration tool: exact on exact points, unbiased under noise, robust
// to outliers, and the concentric two-ring fit.

#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <random>

#include "omnipose/calibrate/circle_fit.hpp"

namespace omnipose::calibrate {
namespace {

constexpr double kPi = std::numbers::pi;

std::vector<Eigen::Vector2d> arc(const Circle& c, int n, double from, double to, double noise,
                                 std::mt19937_64& rng) {
  std::normal_distribution<double> g(0.0, noise);
  std::vector<Eigen::Vector2d> pts;
  for (int i = 0; i < n; ++i) {
    const double a = from + (to - from) * i / n;
    const double r = c.radius + (noise > 0 ? g(rng) : 0.0);
    pts.emplace_back(c.center.x() + r * std::cos(a), c.center.y() + r * std::sin(a));
  }
  return pts;
}

TEST(CircleFit, ThroughThreePoints) {
  const auto c = circleThrough({0, 0}, {2, 0}, {1, 1});
  ASSERT_TRUE(c);
  EXPECT_NEAR(c->center.x(), 1.0, 1e-12);
  EXPECT_NEAR(c->center.y(), 0.0, 1e-12);
  EXPECT_NEAR(c->radius, 1.0, 1e-12);
  EXPECT_FALSE(circleThrough({0, 0}, {1, 1}, {2, 2}));  // collinear
}

TEST(CircleFit, AlgebraicAndGeometricAreExactOnExactPoints) {
  std::mt19937_64 rng(1);
  const Circle truth{{321.7, 248.2}, 187.3};
  for (double span : {2 * kPi, kPi / 3}) {  // full circle and a 60 degree arc
    const auto pts = arc(truth, 90, 0.4, 0.4 + span, 0.0, rng);
    const auto alg = fitCircleAlgebraic(pts);
    ASSERT_TRUE(alg);
    EXPECT_NEAR((alg->center - truth.center).norm(), 0.0, 1e-6) << "span " << span;
    EXPECT_NEAR(alg->radius, truth.radius, 1e-6);
    Circle start = truth;
    start.center += Eigen::Vector2d(5, -4);
    start.radius += 6;
    const auto geo = fitCircleGeometric(pts, start);
    ASSERT_TRUE(geo);
    EXPECT_NEAR((geo->center - truth.center).norm(), 0.0, 1e-6);
    EXPECT_NEAR(geo->radius, truth.radius, 1e-6);
  }
  EXPECT_FALSE(fitCircleAlgebraic(std::vector<Eigen::Vector2d>{{0, 0}, {1, 1}}));
}

TEST(CircleFit, GeometricFitIsAccurateUnderNoise) {
  std::mt19937_64 rng(2);
  const Circle truth{{400.0, 300.0}, 250.0};
  const auto pts = arc(truth, 720, 0, 2 * kPi, 0.5, rng);
  const auto alg = fitCircleAlgebraic(pts);
  ASSERT_TRUE(alg);
  const auto geo = fitCircleGeometric(pts, *alg);
  ASSERT_TRUE(geo);
  // Standard error of the centre ~ sigma * sqrt(2 / n) = 0.026 px.
  EXPECT_LT((geo->center - truth.center).norm(), 0.1);
  EXPECT_NEAR(geo->radius, truth.radius, 0.1);
}

TEST(CircleFit, RansacIgnoresOutliers) {
  std::mt19937_64 rng(3);
  const Circle truth{{200.5, 180.25}, 120.0};
  auto pts = arc(truth, 300, 0, 2 * kPi, 0.3, rng);
  // 40 % outliers: scene edges scattered over the ring's neighbourhood.
  std::uniform_real_distribution<double> u(60.0, 340.0);
  for (int i = 0; i < 200; ++i) pts.emplace_back(u(rng), u(rng) - 20.0);
  RansacOptions o;
  o.inlier_threshold = 1.5;
  const auto fit = fitCircleRansac(pts, o);
  ASSERT_TRUE(fit);
  EXPECT_LT((fit->circle.center - truth.center).norm(), 0.1);
  EXPECT_NEAR(fit->circle.radius, truth.radius, 0.1);
  // Almost all true points are inliers, few outliers are.
  int true_inliers = 0;
  for (int i : fit->inliers) true_inliers += i < 300;
  EXPECT_GE(true_inliers, 295);
  EXPECT_LE(static_cast<int>(fit->inliers.size()) - true_inliers, 10);
  EXPECT_LT(fit->rms, 0.5);
}

TEST(CircleFit, RansacRespectsRadiusAndCentrePriors) {
  std::mt19937_64 rng(4);
  // Two concentric rings: asking for radii near the small one must return the small one.
  auto pts = arc({{100, 100}, 40}, 200, 0, 2 * kPi, 0.2, rng);
  const auto big = arc({{100, 100}, 90}, 400, 0, 2 * kPi, 0.2, rng);
  pts.insert(pts.end(), big.begin(), big.end());
  RansacOptions o;
  o.min_radius = 30;
  o.max_radius = 50;
  o.center_prior = Eigen::Vector2d(102, 98);
  o.max_center_offset = 10;
  const auto fit = fitCircleRansac(pts, o);
  ASSERT_TRUE(fit);
  EXPECT_NEAR(fit->circle.radius, 40.0, 0.1);
}

TEST(CircleFit, ConcentricFitSharesOneCentre) {
  std::mt19937_64 rng(5);
  const Eigen::Vector2d c(287.3, 466.9);
  const auto inner = arc({c, 110}, 400, 0, 2 * kPi, 0.5, rng);
  const auto outer = arc({c, 230}, 300, 0.5, 2 * kPi - 0.5, 0.5, rng);  // cut by the border
  ConcentricFit init;
  init.center = c + Eigen::Vector2d(3, -2);
  init.radius1 = 105;
  init.radius2 = 236;
  const auto fit = fitConcentric(inner, outer, init);
  ASSERT_TRUE(fit);
  EXPECT_LT((fit->center - c).norm(), 0.1);
  EXPECT_NEAR(fit->radius1, 110.0, 0.1);
  EXPECT_NEAR(fit->radius2, 230.0, 0.1);
  EXPECT_NEAR(fit->rms, 0.5, 0.1);
}

}  // namespace
}  // namespace omnipose::calibrate
