#pragma once
/// \file gyro.hpp
/// The robot's gyro in the camera's terms: its samples, and the camera's rotation between two
/// instants integrated from them (DESIGN.md section 2). Where the samples come from (imu.csv,
/// LCM, IIO) is the business of io/ and the daemon; this header knows no source.

#include <Eigen/Core>

#include <cstddef>
#include <optional>
#include <span>

namespace omnipose {

struct ImuCalibration;

/// A rate larger than this about any axis is not a measurement, rad/s (MEMS gyros measure at
/// most 2000-4000 deg/s, 35-70 rad/s).
inline constexpr double kMaxGyroRate = 100.0;

/// An interval between samples longer than this many median intervals is a gap: the gyro
/// cannot tell the motion across it.
inline constexpr double kGyroGapIntervals = 5.0;

/// One gyro sample.
struct GyroSample {
  double t = 0.0;                                  ///< seconds, on the IMU's clock
  Eigen::Vector3d rate = Eigen::Vector3d::Zero();  ///< rad/s, about the IMU's x, y, z axes
};

/// The camera's rotation from camera time t0 to camera time t1 (seconds), R_{c(t0)}^T R_{c(t1)}
/// in the camera's axes at t0 (DESIGN.md section 2's R for a pair), integrated from `samples`
/// (t strictly increasing) after removing `bias` (rad/s, IMU axes) and turning the rates into
/// camera axes with `imu.rotation`; a sample stamped t is taken at camera time
/// t + imu.time_offset_s. Between two samples the rate is the cubic through the four around
/// them (fewer at the recording's ends), and each piece is one fourth-order Magnus step (the
/// rate at two Gauss points, with the coning term of a turning axis): the error falls with
/// the fourth power of the sampling interval on a smooth motion. t1 < t0 gives the inverse
/// rotation.
///
/// nullopt when the samples do not cover [t0, t1] (the first taken after min(t0, t1) or the
/// last before max(t0, t1)) or two samples inside it are more than `max_gap_s` apart: the
/// gyro cannot tell that interval and the caller falls back to the images; also when the
/// result is not finite (times too far apart for doubles: never a rotation with a NaN).
std::optional<Eigen::Matrix3d> integrateGyro(std::span<const GyroSample> samples,
                                             const ImuCalibration& imu,
                                             const Eigen::Vector3d& bias, double t0, double t1,
                                             double max_gap_s);

/// The camera's angular velocity at camera time t (seconds), rad/s about the camera's axes:
/// the rate of `samples` there as integrateGyro() interpolates it (the cubic through the
/// four samples around t), less `bias` (IMU axes), turned into camera axes. nullopt when t
/// lies outside the samples or between two more than `max_gap_s` apart.
std::optional<Eigen::Vector3d> gyroRateAt(std::span<const GyroSample> samples,
                                          const ImuCalibration& imu, const Eigen::Vector3d& bias,
                                          double t, double max_gap_s);

/// How many of `samples` (on the IMU's clock, in the order received) a live stream has
/// delivered by the time the frame captured at camera time `frame_time` (seconds) has been
/// read out: the count before the first sample stamped after frame_time + |readout_s| + 10 ms
/// on the camera's clock (`imu`'s offset). Pass the readout plus half the exposure time where
/// the calibration states one (the last row is exposed until then). For giving a recording
/// to Odometry::addGyro() as it would have arrived (call it with the samples not yet given).
std::size_t gyroSamplesArrivedBy(std::span<const GyroSample> samples, const ImuCalibration& imu,
                                 double readout_s, double frame_time);

}  // namespace omnipose
