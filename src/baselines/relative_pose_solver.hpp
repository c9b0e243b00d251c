#pragma once
// Robust relative pose from bearing correspondences through OpenGV (private to
// omnipose_baselines; OpenGV headers stay in relative_pose_solver.cpp).

#include <Eigen/Core>
#include <vector>

#include "omnipose/baselines/feature_motion_estimator.hpp"

namespace omnipose::baselines {

struct RelativePoseSettings {
  Solver solver = Solver::kFivePoint;
  double threshold_rad = 0.0;  ///< angular inlier threshold alpha (OpenGV: 1 - cos(alpha))
  int max_iterations = 1000;
  double probability = 0.999;
  bool refine = true;
};

/// (R, t) with P_previous = R P_current + t, i.e. OpenGV's (R12, t12) with frame 1 = the
/// previous frame; t has unit norm (five_point) or is zero (rotation_only).
struct RelativePoseResult {
  bool ok = false;  ///< false: RANSAC found no model
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d translation = Eigen::Vector3d::Zero();
  std::vector<int> inliers;      ///< indices into the correspondences
  int iterations = 0;            ///< RANSAC iterations
  double residual_rms_rad = 0.0; ///< RMS angular residual of the inliers
};

/// Seeded (deterministic) RANSAC on bearings f_previous[i] <-> f_current[i].
/// Requires f_previous.size() == f_current.size().
RelativePoseResult solveRelativePose(const std::vector<Eigen::Vector3d>& f_previous,
                                     const std::vector<Eigen::Vector3d>& f_current,
                                     const RelativePoseSettings& settings);

}  // namespace omnipose::baselines
