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

/// The windows of the pass that made a frame's estimate (OdometryResult::windows), one entry
/// per window, and the shift that pass's fitted motion predicts at each
/// (predictWindowShiftPx): what fit_diagnostics_t carries. Empty for a frame without one.
struct WindowArrays {
  Eigen::VectorXd center_u, du, dv, rotation, scale, confidence, model_du, model_dv, weight,
      moving_fraction;
  Eigen::Matrix<bool, Eigen::Dynamic, 1> valid, masked;
  bool refined = false;
  double gamma = 0.0;           ///< radians per panorama column
  double forward_column = 0.0;  ///< column of +x: a window's azimuth is gamma (u - this)
};

/// How a panorama's columns map to azimuth and the fit's window attenuation: what turns a
/// fitted motion into each window's predicted shift in pixels.
struct WindowGeometry {
  double gamma = 0.0;           ///< radians per column
  double forward_column = 0.0;  ///< column of +x
  double kappa = 1.0;           ///< Odometry::windowAttenuation()
};

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
  Eigen::Matrix4d map_pose = Eigen::Matrix4d::Identity();
  bool loop_closed = false;
  std::int64_t loop_place_sequence = -1;
  int places = 0;
  int segment = 0;
  std::int64_t sequence = -1;
  std::int64_t reference_sequence = -1;
  std::int64_t keyframe_sequence = -1;
  int frames_since_keyframe = 0;
  StageTiming timing;
  WindowArrays windows;
};

/// The result of process() for a frame stamped `time_s`: an error's code and message, or the
/// motion, pose, status and windows (`geometry` gives their fitted shifts).
FrameResult toFrameResult(const Expected<OdometryResult>& result, double time_s,
                          const WindowGeometry& geometry);

/// The geometry of `odometry`'s windows over `calibration`'s panorama.
WindowGeometry windowGeometry(const Calibration& calibration, const Odometry& odometry);

}  // namespace omnipose::python
