#pragma once
/// \file frame_rotation.hpp
/// The camera's rotation within one frame, from the gyro (private to the core library): a
/// rolling-shutter frame's rows are captured over its readout, and the gyro tells how the
/// camera turned from the frame's timestamp to each row (DESIGN.md section 3, "Rolling
/// shutter with a gyro"); a row exposed while the camera turns shows the mean of the poses
/// over its exposure (section 3, "Motion blur").
///
/// Realtime: the constructor allocates; measure(), turnAt(), exposedTurnAt() and copies
/// between two constructed alike allocate nothing and never throw.

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

  /// For capture times in [0, span_s] after the timestamp (|span_s|: the readout), each
  /// exposed for up to `max_exposure_s` seconds centred on it (>= 0).
  explicit FrameRotation(double span_s = 0.0, double max_exposure_s = 0.0);

  /// The rotation from camera time `time` (the frame's timestamp, seconds) over the span
  /// widened by half the exposure on either side, integrated from the gyro's `samples`
  /// (integrateGyro(), gyroRateAt()). False, and not known(), when the samples do not cover
  /// [time - exposure / 2, time + span + exposure / 2] or have a gap there, and when the
  /// frame's exposure, `exposure_s` seconds (0: an instant), is not within [0, maxExposure()].
  bool measure(std::span<const GyroSample> samples, const ImuCalibration& imu,
               const Eigen::Vector3d& bias, double time, double max_gap_s, double exposure_s);
  bool known() const { return known_; }
  void forget() { known_ = false; }
  /// The exposure of the frame measured last, seconds (0 before any).
  double exposure() const { return exposure_; }
  /// The longest exposure measure() takes, seconds.
  double maxExposure() const { return max_exposure_; }

  /// The rotation vector from the timestamp to `s` seconds after it, radians, in the camera's
  /// axes at the timestamp: the cubic Hermite curve through the kept samples and their rates
  /// (beyond them, on along the end's rate). Requires known().
  Eigen::Vector3d turnAt(double s) const;

  /// The mean of turnAt() over the exposure centred `s` seconds after the timestamp: what a
  /// row captured then shows (the blurred image's pose, to first order in the turn within
  /// the exposure). turnAt(s) without an exposure. Requires known().
  Eigen::Vector3d exposedTurnAt(double s) const;

 private:
  /// Spaces the kept samples over the span and `exposure_s`.
  void layOut(double exposure_s);

  double span_ = 0.0;          ///< |span_s|, seconds
  double max_exposure_ = 0.0;  ///< seconds
  double step_ = 0.0;
  double origin_ = 0.0;    ///< seconds after the timestamp of the first kept sample (<= 0)
  double exposure_ = 0.0;  ///< seconds
  std::size_t count_ = 1;  ///< kept samples in use, the first count_ of turn_ and rate_
  /// At origin_ + i * step_ after the timestamp; sized once for the longest exposure.
  std::vector<Eigen::Vector3d> turn_, rate_;
  bool known_ = false;
};

}  // namespace omnipose::pipeline
