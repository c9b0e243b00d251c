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

#include "omnipose/io/trajectory.hpp"

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

/// Drift of a chained trajectory's attitude: how far the estimated orientation wanders from
/// the true one over a sequence (what a controller integrating the poses sees), against the
/// per-pair errors of evaluate(). The estimate is aligned by its first pose only (no scale,
/// no fit): for the first estimated pose whose timestamp matches a ground-truth pose (frame
/// a), R_align = R_gt(a) * R_est(a)^T, and every matched pose k has the error rotation
///   E_k = R_gt(k)^T * R_align * R_est(k),   error angle e_k = angle(E_k)
/// (the rotation part of evo_ape's "angle_deg" relation with --align_origin). Positions are
/// not compared (the estimate's are up to scale).
struct DriftResult {
  int poses_expected = 0;  ///< ground-truth poses
  int poses_matched = 0;   ///< of those, with an estimated pose at the same timestamp
  double start_timestamp = 0.0;  ///< the aligned pose (first match), seconds
  double end_timestamp = 0.0;    ///< the last matched pose, seconds
  bool end_is_last = false;      ///< whether that is the last ground-truth pose
  double end_error = 0.0;        ///< e at the last matched pose, radians
  /// rotvec(E) at the last matched pose (axes of the true camera frame: x roll, y pitch,
  /// z yaw), radians.
  Eigen::Vector3d end_error_rotvec = Eigen::Vector3d::Zero();
  double ate_rmse = 0.0;         ///< sqrt(mean e_k^2) over the matched poses, radians
  double max_error = 0.0;        ///< max e_k, radians
  double max_timestamp = 0.0;    ///< where the max occurs, seconds
  std::vector<double> timestamps;  ///< of the matched poses, seconds (ground-truth order)
  std::vector<double> errors;      ///< e_k of the matched poses, radians
};

/// Drift of `estimate` against `groundtruth`; poses are matched by timestamp (within
/// options.time_tolerance; EvaluationOptions::min_translation is not used). Throws
/// std::invalid_argument when no estimated pose matches a ground-truth pose.
DriftResult evaluateDrift(const std::vector<StampedPose>& groundtruth,
                          const std::vector<StampedPose>& estimate,
                          const EvaluationOptions& options = {});

/// Human-readable summary of a drift result and the per-pair result of the same files
/// (degrees for drift, milliradians for eps).
std::string formatDriftTable(const DriftResult& drift, const EvaluationResult& pairs,
                             const std::string& title);
/// One JSON object: the drift statistics (radians) and the pairs' eps statistics
/// ("eps": rmse, max, count; radians), "pairs_missing".
std::string formatDriftJson(const DriftResult& drift, const EvaluationResult& pairs,
                            const std::string& name);
/// Per matched pose CSV: "t,error_rad" (header + one row per pose).
std::string formatDriftCsv(const DriftResult& drift);

/// Human-readable table of the statistics (radians and degrees).
std::string formatTable(const EvaluationResult& result, const std::string& title);
/// One JSON object with the statistics (no per-pair data).
std::string formatJson(const EvaluationResult& result, const std::string& name);
/// Per-pair CSV (header + one row per evaluated pair).
std::string formatPairsCsv(const EvaluationResult& result);

}  // namespace omnipose
