#include "omnipose/evaluation.hpp"

#include <gtest/gtest.h>

#include <numbers>

namespace omnipose {
namespace {

std::vector<StampedPose> trajectory(int n, const Eigen::Vector3d& step_rotvec,
                                    const Eigen::Vector3d& step_t) {
  std::vector<StampedPose> poses;
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
  step.linear() = rotationFromVector(step_rotvec);
  step.translation() = step_t;
  for (int i = 0; i < n; ++i) {
    poses.push_back({0.1 * i, T});
    T = T * step;
  }
  return poses;
}

TEST(Evaluation, IdentityEstimateOfIdentityIsPerfect) {
  const auto gt = trajectory(5, Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero());
  const auto r = evaluate(gt, gt);
  EXPECT_EQ(r.pairs.size(), 4u);
  EXPECT_EQ(r.pairs_missing, 0);
  EXPECT_DOUBLE_EQ(r.angle.rmse, 0.0);
  EXPECT_EQ(r.translation_direction.count, 0);  // no motion, no direction
}

TEST(Evaluation, KnownErrorOnOneAxis) {
  const auto gt = trajectory(6, Eigen::Vector3d(0, 0, 0.05), Eigen::Vector3d::Zero());
  const auto est = trajectory(6, Eigen::Vector3d(0, 0.1, 0.05), Eigen::Vector3d::Zero());
  const auto r = evaluate(gt, est);
  EXPECT_NEAR(r.roll.rmse, 0.0, 1e-12);
  EXPECT_NEAR(r.yaw.rmse, 0.0, 1e-12);
  // rotvec of the combined (0, 0.1, 0.05) step differs from gt by 0.1 in y only.
  EXPECT_NEAR(r.pitch.rmse, 0.1, 1e-12);
  EXPECT_NEAR(r.pitch.max, 0.1, 1e-12);
  EXPECT_NEAR(r.angle.rmse, 0.1, 2e-3);  // angle(R_gt^T R_est), about 0.1
}

TEST(Evaluation, ReversedTranslationIsPi) {
  const auto gt = trajectory(4, Eigen::Vector3d::Zero(), Eigen::Vector3d(0.1, 0, 0));
  const auto est = trajectory(4, Eigen::Vector3d::Zero(), Eigen::Vector3d(-3.0, 0, 0));
  const auto r = evaluate(gt, est);
  EXPECT_EQ(r.translation_direction.count, 3);
  EXPECT_NEAR(r.translation_direction.rmse, std::numbers::pi, 1e-9);
  // Scale does not matter, direction does.
  const auto same_dir = trajectory(4, Eigen::Vector3d::Zero(), Eigen::Vector3d(7.0, 0, 0));
  EXPECT_NEAR(evaluate(gt, same_dir).translation_direction.rmse, 0.0, 1e-9);
}

TEST(Evaluation, MissingPosesAreCountedNotGuessed) {
  const auto gt = trajectory(6, Eigen::Vector3d(0.01, 0, 0), Eigen::Vector3d::Zero());
  auto est = gt;
  est.erase(est.begin() + 2);  // frame 2 lost: pairs (1,2) and (2,3) are missing
  const auto r = evaluate(gt, est);
  EXPECT_EQ(r.pairs_expected, 5);
  EXPECT_EQ(r.pairs_missing, 2);
  EXPECT_EQ(r.pairs.size(), 3u);
  EXPECT_NE(formatJson(r, "x").find("\"pairs_missing\": 2"), std::string::npos);
  EXPECT_NE(formatTable(r, "x").find("3 of 5 pairs"), std::string::npos);
}

}  // namespace
}  // namespace omnipose
