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
/// from IMU rotation), so beta - b = -C^T log(G^T R) / dt. The estimate is the per-axis
/// median of the first kWarmUp readings, then an exponential average over kTimeConstantS
/// seconds of pairs (the bias drifts). A pair whose images a person walking by turned gives
/// a reading tens of times the images' noise: the median leaves such readings out of the
/// start, and after it a reading further from the estimate than kGateSigmas of the readings'
/// scatter (at least kMinGateRadS) is not used. A reading beyond kMaxBiasRadS is no bias.
///
/// Realtime: no allocation, never throws.

#include <Eigen/Core>
#include <array>
#include <cstdint>

namespace omnipose::pipeline {

class GyroBias {
 public:
  static constexpr int kWarmUp = 30;              ///< readings whose median starts it
  static constexpr double kTimeConstantS = 5.0;   ///< the EMA's, seconds of pairs
  /// A reading further than this from zero is no MEMS gyro's bias (30 deg/s), rad/s.
  static constexpr double kMaxBiasRadS = 0.5;
  /// After the warm-up, a reading further from the estimate than kGateSigmas times the
  /// readings' scatter (rms per axis, times sqrt(3)), and never less than kMinGateRadS
  /// (0.17 deg/s), is not used.
  static constexpr double kGateSigmas = 4.0;
  static constexpr double kMinGateRadS = 0.003;

  /// One pair: the images' rotation `images` and the gyro's `gyro` (integrated with bias()
  /// removed) from the reference frame to the current one over `dt` seconds; `camera_from_imu`
  /// the calibration's rotation. False when not used (dt not positive, an outlier).
  bool update(const Eigen::Matrix3d& images, const Eigen::Matrix3d& gyro, double dt,
              const Eigen::Matrix3d& camera_from_imu);
  /// The estimate, rad/s about the IMU's axes (zero before any reading).
  const Eigen::Vector3d& bias() const { return bias_; }
  /// Readings used so far.
  std::int64_t readings() const { return readings_; }
  /// Whether the warm-up's median has been taken (kWarmUp readings): before, a few pairs that
  /// people bent can still move the estimate far.
  bool settled() const { return readings_ >= kWarmUp; }
  /// One standard deviation of the estimate, rad/s (about each axis): the readings' scatter
  /// over the readings averaged; infinity before two readings.
  double sigma() const;

 private:
  /// The median and the scatter (from the median absolute deviation) of first_[0, readings_).
  void startFromFirst();

  Eigen::Vector3d bias_ = Eigen::Vector3d::Zero();
  double scatter_ = 0.0;  ///< mean squared deviation of the readings from the estimate, per axis
  std::int64_t readings_ = 0;
  std::array<Eigen::Vector3d, kWarmUp> first_{};  ///< the warm-up's readings (absolute)
};

}  // namespace omnipose::pipeline
