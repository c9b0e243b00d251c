#pragma once
/// \file evaluation.hpp
/// Scores an estimated trajectory against ground truth, per consecutive frame pair (the
/// paper's protocol): for each pair (k-1, k) present in both, the relative motions
/// inverse(T_{k-1}) * T_k are compared.
///   rotation error vector  e = rotvec(R_est) - rotvec(R_gt)   (roll = x, pitch = y, yaw = z)
///   rotation error angle   eps = angle(R_gt^T R_est)
///   translation direction  angle(t_est, t_gt), where |t_gt| > min_translation
/// Poses are matched by timestamp (within `time_tolerance`).

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "omnipose/trajectory.hpp"

namespace omnipose {

struct PairError {
  double t_prev = 0.0, t = 0.0;            ///< timestamps of the pair, seconds
  Eigen::Vector3d gt_rotvec = Eigen::Vector3d::Zero();   ///< radians
  Eigen::Vector3d est_rotvec = Eigen::Vector3d::Zero();  ///< radians
  Eigen::Vector3d rotvec_error = Eigen::Vector3d::Zero();  ///< est - gt, radians
  double angle_error = 0.0;                ///< radians
  std::optional<double> translation_direction_error;  ///< radians, when the true step moves
};

struct ErrorStats {
  double rmse = 0.0;
  double max = 0.0;
  int count = 0;
};

struct EvaluationResult {
  std::vector<PairError> pairs;
  int pairs_expected = 0;  ///< consecutive ground-truth pairs
  int pairs_missing = 0;   ///< of those, not in the estimate
  ErrorStats roll, pitch, yaw;  ///< rotation-vector components x, y, z
  ErrorStats angle;             ///< eps
  ErrorStats translation_direction;
};

struct EvaluationOptions {
  double time_tolerance = 1e-3;   ///< seconds
  double min_translation = 1e-6;  ///< ground-truth steps shorter than this have no direction
};

EvaluationResult evaluate(const std::vector<StampedPose>& groundtruth,
                          const std::vector<StampedPose>& estimate,
                          const EvaluationOptions& options = {});

/// Human-readable table of the statistics (radians and degrees).
std::string formatTable(const EvaluationResult& result, const std::string& title);
/// One JSON object with the statistics (no per-pair data).
std::string formatJson(const EvaluationResult& result, const std::string& name);
/// Per-pair CSV (header + one row per evaluated pair).
std::string formatPairsCsv(const EvaluationResult& result);

}  // namespace omnipose
