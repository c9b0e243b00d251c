#pragma once
/// \file result_convert.hpp
/// One frame's outcome of Odometry::process as the Python module returns it: copied out of
/// OdometryResult (whose window span dies with the next frame) into plain values.

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <string>

#include "omnipose/error.hpp"
#include "omnipose/odometry.hpp"

namespace omnipose::python {

struct FrameResult {
  double time_s = 0.0;                     ///< the frame's capture time given, seconds
  std::optional<std::string> error;        ///< error code name (bad_frame, implausible); none when ok
  std::string message;                     ///< the error's message; empty when ok
  std::optional<std::string> state;        ///< toString(TrackState); none after an error
  std::string status = "lost";             ///< fit status (ok, degraded, lost)
  bool has_motion = false;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  Eigen::Vector3d rotation_vector = Eigen::Vector3d::Zero();  ///< omega, radians
  Eigen::Vector3d tau = Eigen::Vector3d::Zero();              ///< t / rho
  Eigen::Vector3d translation_direction = Eigen::Vector3d::Zero();
  double tau_norm = 0.0;
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();
  double residual_rms_px = 0.0;
  int windows_used = 0;
  int windows_total = 0;
  Eigen::Matrix4d pose = Eigen::Matrix4d::Identity();
  int segment = 0;
  std::int64_t sequence = -1;
  std::int64_t reference_sequence = -1;
  std::int64_t keyframe_sequence = -1;
  int frames_since_keyframe = 0;
  StageTiming timing;
};

/// The result of process() for a frame stamped `time_s`: an error's code and message, or the
/// motion, pose and status.
FrameResult toFrameResult(const Expected<OdometryResult>& result, double time_s);

}  // namespace omnipose::python
