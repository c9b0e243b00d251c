#pragma once
/// \file gyro_bias.hpp
/// The gyro's bias, tracked from the images (private to the core library; DESIGN.md section
/// 3, "The gyro's bias and bridging").
///
/// A MEMS gyro's bias (0.1-1 deg/s, drifting with temperature) cancels within a frame pair's
/// rows, but not over a pair or across an outage the gyro bridges: there every second of it
/// is a degree of heading. Each pair the images measured well (kOk, against the previous
/// frame) gives one reading of it: with the samples integrated after removing the estimate
/// b, the gyro's rotation G and the images' R differ by exp(-C (beta - b) dt) (C the camera
/// from IMU rotation), so beta - b = -C^T log(G^T R) / dt. The estimate is the mean of the
/// first kWarmUp readings, then an exponential average over kTimeConstantS seconds of pairs
/// (the bias drifts). A reading beyond kMaxBiasRadS is no bias; after the warm-up one further
/// than kMaxReadingRadS from the estimate is not used either (a pair the images got wrong
/// cannot pull it far).
///
/// Realtime: no allocation, never throws.

#include <Eigen/Core>
#include <cstdint>

namespace omnipose::pipeline {

class GyroBias {
 public:
  static constexpr int kWarmUp = 30;              ///< readings averaged before the EMA
  static constexpr double kTimeConstantS = 5.0;   ///< the EMA's, seconds of pairs
  /// A reading further than this from the estimate is not used, rad/s: always 0.5 (30
  /// deg/s, no MEMS gyro's bias), after the warm-up 0.05 (3 deg/s).
  static constexpr double kMaxBiasRadS = 0.5;
  static constexpr double kMaxReadingRadS = 0.05;

  /// One pair: the images' rotation `images` and the gyro's `gyro` (integrated with bias()
  /// removed) from the reference frame to the current one over `dt` seconds; `camera_from_imu`
  /// the calibration's rotation. False when not used (dt not positive, an outlier).
  bool update(const Eigen::Matrix3d& images, const Eigen::Matrix3d& gyro, double dt,
              const Eigen::Matrix3d& camera_from_imu);
  /// The estimate, rad/s about the IMU's axes (zero before any reading).
  const Eigen::Vector3d& bias() const { return bias_; }
  /// Readings used so far.
  std::int64_t readings() const { return readings_; }
  /// One standard deviation of the estimate, rad/s (about each axis): the readings' scatter
  /// over the readings averaged; infinity before two readings.
  double sigma() const;

 private:
  Eigen::Vector3d bias_ = Eigen::Vector3d::Zero();
  double scatter_ = 0.0;  ///< mean squared deviation of the readings from the estimate
  std::int64_t readings_ = 0;
};

}  // namespace omnipose::pipeline
