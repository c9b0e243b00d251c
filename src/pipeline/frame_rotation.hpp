#pragma once
/// \file frame_rotation.hpp
/// The camera's rotation within one frame, from the gyro (private to the core library): a
/// rolling-shutter frame's rows are captured over its readout, and the gyro tells how the
/// camera turned from the frame's timestamp to each row (DESIGN.md section 3, "Rolling
/// shutter with a gyro").
///
/// Realtime: the constructor allocates; measure(), turnAt() and copies between two of the
/// same span allocate nothing and never throw.

#include <Eigen/Core>
#include <span>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/gyro.hpp"

namespace omnipose::pipeline {

class FrameRotation {
 public:
  /// Spacing of the samples of the rotation kept, seconds.
  static constexpr double kStepS = 0.001;

  /// For capture times in [0, span_s] after the timestamp (|readout_s|).
  explicit FrameRotation(double span_s = 0.0);

  /// The rotation from camera time `time` (the frame's timestamp, seconds) over the span,
  /// integrated from the gyro's `samples` (integrateGyro(), gyroRateAt()). False, and not
  /// known(), when the samples do not cover [time, time + span] or have a gap there.
  bool measure(std::span<const GyroSample> samples, const ImuCalibration& imu,
               const Eigen::Vector3d& bias, double time, double max_gap_s);
  bool known() const { return known_; }
  void forget() { known_ = false; }

  /// The rotation vector from the timestamp to `s` seconds after it, radians, in the camera's
  /// axes at the timestamp: the cubic Hermite curve through the kept samples and their rates
  /// (beyond the span, the end's rate). Requires known().
  Eigen::Vector3d turnAt(double s) const;

 private:
  double step_ = 0.0;
  std::vector<Eigen::Vector3d> turn_, rate_;  ///< at i * step_ after the timestamp
  bool known_ = false;
};

}  // namespace omnipose::pipeline
