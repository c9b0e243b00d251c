#include "omnipose/eval/evaluation.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

using ::testing::HasSubstr;

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
  EXPECT_THAT(formatJson(r, "x"), HasSubstr("\"pairs_missing\": 2"));
  EXPECT_THAT(formatTable(r, "x"), HasSubstr("3 of 5 pairs"));
}

/// Rotation about z by `angle` radians as a pose.
Eigen::Isometry3d yaw(double angle) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationFromVector(Eigen::Vector3d(0, 0, angle));
  return T;
}

TEST(EvaluationDrift, ConstantYawBiasGrowsLinearlyAndTheStartOffsetIsAlignedAway) {
  // Ground truth turns about every axis; the estimate starts in an arbitrary frame Q and
  // gains a yaw bias b per frame in the camera frame: R_est(k) = Q R_gt(k) Rz(k b), so the
  // aligned error rotation is exactly Rz(k b).
  constexpr int kFrames = 41;
  constexpr double kBias = 2e-4;  // radians per frame
  const auto gt = trajectory(kFrames, Eigen::Vector3d(0.01, -0.02, 0.03), Eigen::Vector3d(0.1, 0, 0));
  Eigen::Isometry3d offset = Eigen::Isometry3d::Identity();
  offset.linear() = rotationFromVector(Eigen::Vector3d(0.3, -1.1, 2.0));
  offset.translation() = Eigen::Vector3d(5, 6, 7);
  std::vector<StampedPose> est;
  for (int k = 0; k < kFrames; ++k) {
    est.push_back({gt[k].timestamp, offset * gt[k].pose * yaw(k * kBias)});
  }
  const DriftResult d = evaluateDrift(gt, est);
  EXPECT_EQ(d.poses_expected, kFrames);
  EXPECT_EQ(d.poses_matched, kFrames);
  EXPECT_TRUE(d.end_is_last);
  EXPECT_DOUBLE_EQ(d.start_timestamp, 0.0);
  EXPECT_DOUBLE_EQ(d.end_timestamp, gt.back().timestamp);
  EXPECT_NEAR(d.end_error, (kFrames - 1) * kBias, 1e-12);
  EXPECT_NEAR(d.end_error_rotvec.z(), (kFrames - 1) * kBias, 1e-12);
  EXPECT_NEAR(d.end_error_rotvec.head<2>().norm(), 0.0, 1e-12);
  // RMS of k b over k = 0 .. n-1: b sqrt((n-1)(2n-1)/6).
  EXPECT_NEAR(d.ate_rmse, kBias * std::sqrt((kFrames - 1) * (2.0 * kFrames - 1) / 6.0), 1e-12);
  EXPECT_NEAR(d.max_error, (kFrames - 1) * kBias, 1e-12);
  EXPECT_DOUBLE_EQ(d.max_timestamp, gt.back().timestamp);
  ASSERT_EQ(d.errors.size(), static_cast<std::size_t>(kFrames));
  for (int k = 0; k < kFrames; ++k) EXPECT_NEAR(d.errors[k], k * kBias, 1e-12) << k;

  // The same bias on a pure-yaw truth: every pair is off by exactly b.
  const auto gt_yaw = trajectory(kFrames, Eigen::Vector3d(0, 0, 0.05), Eigen::Vector3d::Zero());
  std::vector<StampedPose> est_yaw;
  for (int k = 0; k < kFrames; ++k) est_yaw.push_back({gt_yaw[k].timestamp, gt_yaw[k].pose * yaw(k * kBias)});
  const EvaluationResult pairs = evaluate(gt_yaw, est_yaw);
  EXPECT_NEAR(pairs.angle.rmse, kBias, 1e-12);
  const DriftResult dy = evaluateDrift(gt_yaw, est_yaw);
  EXPECT_NEAR(dy.end_error, (kFrames - 1) * kBias, 1e-12);
  const std::string table = formatDriftTable(dy, pairs, "yaw");
  EXPECT_THAT(table, HasSubstr("end-point rotation error      0.4584 deg"));
  EXPECT_THAT(table, HasSubstr("per-pair eps RMSE             0.2000 mrad (40 pairs, 0 missing)"));
  const std::string json = formatDriftJson(dy, pairs, "yaw");
  EXPECT_THAT(json, HasSubstr("\"end_error\": 0.008"));
  EXPECT_THAT(json, HasSubstr("\"end_is_last\": true"));
  const std::string csv = formatDriftCsv(dy);
  EXPECT_EQ(std::count(csv.begin(), csv.end(), '\n'), kFrames + 1);
}

TEST(EvaluationDrift, AlignsAtTheFirstMatchAndEndsAtTheLastMatch) {
  // A yaw drift that reverses: 0 at frames 0 and 20, largest at frame 10; the estimate
  // lacks frames 0 and 20 (so it is aligned at frame 1 and ends at frame 19).
  const auto gt = trajectory(21, Eigen::Vector3d(0, 0, 0.02), Eigen::Vector3d::Zero());
  std::vector<StampedPose> est;
  for (int k = 1; k < 20; ++k) {
    const double drift = 1e-3 * (10 - std::abs(10 - k));
    est.push_back({gt[k].timestamp, gt[k].pose * yaw(drift)});
  }
  const DriftResult d = evaluateDrift(gt, est);
  EXPECT_EQ(d.poses_matched, 19);
  EXPECT_DOUBLE_EQ(d.start_timestamp, gt[1].timestamp);
  EXPECT_DOUBLE_EQ(d.end_timestamp, gt[19].timestamp);
  EXPECT_FALSE(d.end_is_last);
  // Aligned at frame 1 (drift 1e-3 there): all rotations are about z, so the errors are
  // |drift(k) - 1e-3|.
  EXPECT_NEAR(d.end_error, 0.0, 1e-12);
  EXPECT_NEAR(d.max_error, 9e-3, 1e-12);
  EXPECT_DOUBLE_EQ(d.max_timestamp, gt[10].timestamp);
  EXPECT_THAT(formatDriftTable(d, evaluate(gt, est), "x"), HasSubstr("(not the last frame)"));
  // No common timestamp: an error, not a zero.
  std::vector<StampedPose> shifted = est;
  for (auto& p : shifted) p.timestamp += 0.05;
  EXPECT_THROW(evaluateDrift(gt, shifted), std::invalid_argument);
  EXPECT_THROW(evaluateDrift(gt, {}), std::invalid_argument);
}

}  // namespace
}  // namespace omnipose
