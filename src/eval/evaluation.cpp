#include "omnipose/eval/evaluation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "common/format.hpp"

namespace omnipose {
namespace {

std::vector<StampedPose> sortedByTime(std::vector<StampedPose> poses) {
  std::sort(poses.begin(), poses.end(),
            [](const StampedPose& a, const StampedPose& b) { return a.timestamp < b.timestamp; });
  return poses;
}

/// Index of the pose with timestamp t (within tol) in a time-sorted trajectory, or -1.
int findPose(const std::vector<StampedPose>& poses, double t, double tol) {
  auto it = std::lower_bound(poses.begin(), poses.end(), t - tol,
                             [](const StampedPose& p, double x) { return p.timestamp < x; });
  if (it != poses.end() && std::abs(it->timestamp - t) <= tol)
    return static_cast<int>(it - poses.begin());
  return -1;
}

void accumulate(ErrorStats& s, double e) {
  s.rmse += e * e;  // sum of squares until finish()
  s.max = std::max(s.max, std::abs(e));
  ++s.count;
}

void finish(ErrorStats& s) { s.rmse = s.count > 0 ? std::sqrt(s.rmse / s.count) : 0.0; }

}  // namespace

EvaluationResult evaluate(const std::vector<StampedPose>& groundtruth,
                          const std::vector<StampedPose>& estimate,
                          const EvaluationOptions& options) {
  const std::vector<StampedPose> est = sortedByTime(estimate);
  EvaluationResult r;
  for (std::size_t k = 1; k < groundtruth.size(); ++k) {
    ++r.pairs_expected;
    const int i0 = findPose(est, groundtruth[k - 1].timestamp, options.time_tolerance);
    const int i1 = findPose(est, groundtruth[k].timestamp, options.time_tolerance);
    if (i0 < 0 || i1 < 0) {
      ++r.pairs_missing;
      continue;
    }
    const Eigen::Isometry3d gt = groundtruth[k - 1].pose.inverse() * groundtruth[k].pose;
    const Eigen::Isometry3d es = est[i0].pose.inverse() * est[i1].pose;
    PairError e;
    e.t_prev = groundtruth[k - 1].timestamp;
    e.t = groundtruth[k].timestamp;
    e.gt_rotvec = rotationVector(gt.rotation());
    e.est_rotvec = rotationVector(es.rotation());
    e.rotvec_error = e.est_rotvec - e.gt_rotvec;
    e.angle_error = rotationVector(gt.rotation().transpose() * es.rotation()).norm();
    const Eigen::Vector3d tg = gt.translation(), te = es.translation();
    if (tg.norm() > options.min_translation) {
      e.translation_direction_error =
          te.norm() > 0 ? std::acos(std::clamp(tg.normalized().dot(te.normalized()), -1.0, 1.0))
                        : std::numbers::pi / 2;  // no estimate of a real step: 90 degrees
    }
    accumulate(r.roll, e.rotvec_error.x());
    accumulate(r.pitch, e.rotvec_error.y());
    accumulate(r.yaw, e.rotvec_error.z());
    accumulate(r.angle, e.angle_error);
    if (e.translation_direction_error) accumulate(r.translation_direction, *e.translation_direction_error);
    r.pairs.push_back(e);
  }
  for (ErrorStats* s : {&r.roll, &r.pitch, &r.yaw, &r.angle, &r.translation_direction}) finish(*s);
  return r;
}

DriftResult evaluateDrift(const std::vector<StampedPose>& groundtruth,
                          const std::vector<StampedPose>& estimate,
                          const EvaluationOptions& options) {
  const std::vector<StampedPose> est = sortedByTime(estimate);
  DriftResult r;
  r.poses_expected = static_cast<int>(groundtruth.size());
  std::optional<Eigen::Matrix3d> align;
  double sum_squares = 0.0;
  for (std::size_t k = 0; k < groundtruth.size(); ++k) {
    const int i = findPose(est, groundtruth[k].timestamp, options.time_tolerance);
    if (i < 0) continue;
    const Eigen::Matrix3d R_gt = groundtruth[k].pose.rotation();
    const Eigen::Matrix3d R_est = est[static_cast<std::size_t>(i)].pose.rotation();
    if (!align) {
      align = R_gt * R_est.transpose();
      r.start_timestamp = groundtruth[k].timestamp;
    }
    const Eigen::Vector3d e = rotationVector(R_gt.transpose() * *align * R_est);
    const double angle = e.norm();
    ++r.poses_matched;
    r.timestamps.push_back(groundtruth[k].timestamp);
    r.errors.push_back(angle);
    sum_squares += angle * angle;
    if (angle > r.max_error || r.poses_matched == 1) {
      r.max_error = angle;
      r.max_timestamp = groundtruth[k].timestamp;
    }
    r.end_timestamp = groundtruth[k].timestamp;
    r.end_error = angle;
    r.end_error_rotvec = e;
    r.end_is_last = k + 1 == groundtruth.size();
  }
  if (r.poses_matched == 0) {
    throw std::invalid_argument("evaluateDrift: no estimated pose has the timestamp of a "
                                "ground-truth pose (tolerance " +
                                std::to_string(options.time_tolerance) + " s)");
  }
  r.ate_rmse = std::sqrt(sum_squares / r.poses_matched);
  return r;
}

std::string formatDriftTable(const DriftResult& d, const EvaluationResult& pairs,
                             const std::string& title) {
  constexpr double kDeg = 180.0 / std::numbers::pi;
  return detail::format(
      "%s: %d of %d poses matched, aligned at t = %.6f s\n"
      "  end-point rotation error  %10.4f deg at t = %.6f s%s"
      " (rotvec %+.4f %+.4f %+.4f deg)\n"
      "  ATE rotation RMSE         %10.4f deg\n"
      "  max rotation error        %10.4f deg at t = %.6f s\n"
      "  per-pair eps RMSE         %10.4f mrad (%d pairs, %d missing)\n",
      title.c_str(), d.poses_matched, d.poses_expected, d.start_timestamp,
      d.end_error * kDeg, d.end_timestamp, d.end_is_last ? "" : " (not the last frame)",
      d.end_error_rotvec.x() * kDeg, d.end_error_rotvec.y() * kDeg,
      d.end_error_rotvec.z() * kDeg, d.ate_rmse * kDeg, d.max_error * kDeg,
      d.max_timestamp, pairs.angle.rmse * 1e3, static_cast<int>(pairs.pairs.size()),
      pairs.pairs_missing);
}

std::string formatDriftJson(const DriftResult& d, const EvaluationResult& pairs,
                            const std::string& name) {
  return detail::format(
      "{\"name\": \"%s\", \"poses_expected\": %d, \"poses_matched\": %d, "
      "\"start_timestamp\": %.6f, \"end_timestamp\": %.6f, \"end_is_last\": %s, "
      "\"end_error\": %.9g, \"end_error_rotvec\": [%.9g, %.9g, %.9g], "
      "\"ate_rmse\": %.9g, \"max_error\": %.9g, \"max_timestamp\": %.6f, "
      "\"eps\": {\"rmse\": %.9g, \"max\": %.9g, \"count\": %d}, "
      "\"pairs_missing\": %d}",
      name.c_str(), d.poses_expected, d.poses_matched, d.start_timestamp,
      d.end_timestamp, d.end_is_last ? "true" : "false", d.end_error,
      d.end_error_rotvec.x(), d.end_error_rotvec.y(), d.end_error_rotvec.z(),
      d.ate_rmse, d.max_error, d.max_timestamp, pairs.angle.rmse, pairs.angle.max,
      pairs.angle.count, pairs.pairs_missing);
}

std::string formatDriftCsv(const DriftResult& d) {
  std::string out = "t,error_rad\n";
  char buf[64];
  for (std::size_t i = 0; i < d.errors.size(); ++i) {
    std::snprintf(buf, sizeof(buf), "%.6f,%.9g\n", d.timestamps[i], d.errors[i]);
    out += buf;
  }
  return out;
}

std::string formatTable(const EvaluationResult& r, const std::string& title) {
  constexpr double kDeg = 180.0 / std::numbers::pi;
  std::string out;
  char buf[256];
  std::snprintf(buf, sizeof(buf), "%s: %d of %d pairs evaluated, %d missing\n", title.c_str(),
                static_cast<int>(r.pairs.size()), r.pairs_expected, r.pairs_missing);
  out += buf;
  out += "  error                 RMSE [rad]   max [rad]   RMSE [deg]\n";
  auto row = [&](const char* name, const ErrorStats& s) {
    std::snprintf(buf, sizeof(buf), "  %-20s %11.6f %11.6f %11.4f\n", name, s.rmse, s.max,
                  s.rmse * kDeg);
    out += buf;
  };
  row("roll (x)", r.roll);
  row("pitch (y)", r.pitch);
  row("yaw (z)", r.yaw);
  row("rotation angle eps", r.angle);
  if (r.translation_direction.count > 0) row("translation dir", r.translation_direction);
  return out;
}

std::string formatJson(const EvaluationResult& r, const std::string& name) {
  auto stats = [](const ErrorStats& s) {
    char buf[128];
    std::snprintf(buf, sizeof(buf), "{\"rmse\": %.9g, \"max\": %.9g, \"count\": %d}", s.rmse,
                  s.max, s.count);
    return std::string(buf);
  };
  char head[256];
  std::snprintf(head, sizeof(head), "{\"name\": \"%s\", \"pairs\": %d, \"pairs_expected\": %d, \"pairs_missing\": %d, ",
                name.c_str(), static_cast<int>(r.pairs.size()), r.pairs_expected, r.pairs_missing);
  return std::string(head) + "\"roll\": " + stats(r.roll) + ", \"pitch\": " + stats(r.pitch) +
         ", \"yaw\": " + stats(r.yaw) + ", \"eps\": " + stats(r.angle) +
         ", \"translation_direction\": " + stats(r.translation_direction) + "}";
}

std::string formatPairsCsv(const EvaluationResult& r) {
  std::string out =
      "t_prev,t,gt_rx,gt_ry,gt_rz,est_rx,est_ry,est_rz,err_rx,err_ry,err_rz,eps,tdir_err\n";
  char buf[512];
  for (const auto& e : r.pairs) {
    std::snprintf(buf, sizeof(buf), "%.6f,%.6f,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%s\n",
                  e.t_prev, e.t, e.gt_rotvec.x(), e.gt_rotvec.y(), e.gt_rotvec.z(),
                  e.est_rotvec.x(), e.est_rotvec.y(), e.est_rotvec.z(), e.rotvec_error.x(),
                  e.rotvec_error.y(), e.rotvec_error.z(), e.angle_error,
                  e.translation_direction_error
                      ? std::to_string(*e.translation_direction_error).c_str()
                      : "");
    out += buf;
  }
  return out;
}

}  // namespace omnipose
