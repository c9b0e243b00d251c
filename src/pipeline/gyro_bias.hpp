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
/// from IMU rotation), so beta - b = -C^T log(G^T R) / dt, with the variance per IMU axis
/// diag(C^T S C) / dt^2 plus the gyro's white noise over the pair (S the images' rotation
/// covariance). Each reading weighs the inverse of that variance: a pair whose images a
/// person walking by turned is also one the fit is less sure of (several times the variance),
/// and weighs less.
///
/// Pairs that translate are kept apart from pairs that turn or stand in place: while the
/// camera translates, the images' yaw drifts with the walls' texture (issue 54's straights),
/// and from straight driving alone that drift and the bias cannot be told apart. Each kind
/// has its own estimate; the translating pairs' counts as off by up to kDrivingYawSigma about
/// the camera's vertical, and the two are combined by their variances (so the pairs that turn
/// or stand set the bias wherever the robot has turned or stood lately, and a robot that only
/// drives still has one).
///
/// Each estimate starts as the per-axis weighted median of the first kWarmUp readings (robust
/// to a minority of readings whose variance does not show the person; its variance from the
/// readings' mean square about it, so that a majority bent the same way is not taken as
/// certain, with Student's t for few readings), then follows a Kalman
/// filter of a bias that walks by kBiasRandomWalk. After the warm-up a reading further from
/// the estimate, on any axis, than kGateSigmas sigmas of a usual reading (the readings' mean
/// inverse variance; a reading that states a larger variance gets no wider gate) is not used:
/// people bend many pairs in a row the same way, which a weight alone would let through.
/// Every sigma is scaled by how far the readings scatter about the estimate against their
/// stated variances (never below what they state). A reading beyond kMaxBiasRadS is no bias.
///
/// Realtime: no allocation, never throws.

#include <Eigen/Core>
#include <array>
#include <cstdint>

namespace omnipose::pipeline {

/// One pair's reading of the bias: the images' rotation and the gyro's over the same pair.
struct GyroBiasReading {
  Eigen::Matrix3d images = Eigen::Matrix3d::Identity();  ///< from the reference frame on
  /// Covariance of the images' rotation (right perturbation, camera axes), rad^2; when not
  /// positive and finite, kUnknownImagesSigma per axis.
  Eigen::Matrix3d images_covariance = Eigen::Matrix3d::Zero();
  Eigen::Matrix3d gyro = Eigen::Matrix3d::Identity();  ///< integrated with bias() removed
  double gyro_variance = 0.0;  ///< of the gyro's rotation from its white noise, rad^2 per axis
  double dt = 0.0;             ///< seconds of the pair
  /// Whether the camera translated over the pair (the fit's translation significant and not
  /// negligible): the images' yaw then drifts with the walls' texture (docs/results/
  /// ANALYSIS.md, "Driving with the gyro"), and such readings are kept apart.
  bool translating = false;
};

class GyroBias {
 public:
  static constexpr int kWarmUp = 30;  ///< readings whose weighted median starts each estimate
  /// Readings before an estimate is used (settled()).
  static constexpr int kSettleReadings = 10;
  /// How fast the bias may wander, rad/s/sqrt(s) (a MEMS gyro's with temperature, 0.006
  /// deg/s/sqrt(s)): with a phone at 30 fps the filter remembers about 5 s of pairs.
  static constexpr double kBiasRandomWalk = 1e-4;
  /// A reading further than this from zero is no MEMS gyro's bias (30 deg/s), rad/s.
  static constexpr double kMaxBiasRadS = 0.5;
  /// After the warm-up, a reading whose distance from the estimate exceeds kGateSigmas
  /// sigmas of a usual reading on any axis is not used.
  static constexpr double kGateSigmas = 4.0;
  /// The images' rotation sigma per axis assumed where a pair gives no covariance (rad).
  static constexpr double kUnknownImagesSigma = 1e-4;
  /// How far the images' yaw rate may drift while the camera translates, rad/s about the
  /// camera's vertical (0.11 deg/s; the drift benchmark's rectangle 0.05, the pool's
  /// straights up to 0.2): the uncertainty the translating pairs' estimate carries.
  static constexpr double kDrivingYawSigma = 2e-3;

  /// One pair's reading. False when not used (dt not positive, an outlier, beyond
  /// kMaxBiasRadS).
  bool update(const GyroBiasReading& reading, const Eigen::Matrix3d& camera_from_imu);
  /// The estimate, rad/s about the IMU's axes (zero before any reading).
  const Eigen::Vector3d& bias() const { return bias_; }
  /// Readings used so far (both kinds).
  std::int64_t readings() const;
  /// Whether the estimate may be used to correct the gyro's rotations (kSettleReadings
  /// readings of one kind): its sigma() tells how far.
  bool settled() const;
  /// One standard deviation of the estimate, rad/s (the RMS over the axes); infinity before
  /// it has settled.
  double sigma() const;

 private:
  /// The estimate from one kind of pairs (IMU axes, rad/s).
  class Filter {
   public:
    /// `value` a reading of variance `variance` per axis over a pair of `dt` seconds. False
    /// when refused.
    bool update(const Eigen::Vector3d& value, const Eigen::Vector3d& variance, double dt);
    /// The bias's random walk over `dt` seconds added to the estimate's variance.
    void walk(double dt);
    const Eigen::Vector3d& estimate() const { return bias_; }
    const Eigen::Vector3d& variance() const { return variance_; }
    std::int64_t readings() const { return readings_; }
    bool settled() const { return readings_ >= kSettleReadings; }

   private:
    /// The weighted median and its variance from first_ and first_weight_ [0, readings_).
    void startFromFirst();
    /// The readings' scatter against their stated variances, never below 1.
    double scale() const;

    Eigen::Vector3d bias_ = Eigen::Vector3d::Zero();
    Eigen::Vector3d variance_ = Eigen::Vector3d::Zero();  ///< of the estimate, rad^2/s^2
    /// Mean squared normalized residual of the readings (1: as their variances state).
    double scatter_ = 1.0;
    /// The readings' mean inverse variance per axis: 1 / it is the variance of a usual pair.
    Eigen::Vector3d typical_weight_ = Eigen::Vector3d::Zero();
    std::int64_t readings_ = 0;
    std::array<Eigen::Vector3d, kWarmUp> first_{};         ///< the warm-up's readings
    std::array<Eigen::Vector3d, kWarmUp> first_weight_{};  ///< their inverse variances
  };
  /// bias_ and variance_ from the two filters.
  void combine(const Eigen::Matrix3d& camera_from_imu);

  Filter still_;   ///< pairs that turn or stand in place
  Filter moving_;  ///< pairs that translate (GyroBiasReading::translating)
  Eigen::Vector3d bias_ = Eigen::Vector3d::Zero();
  Eigen::Vector3d variance_ = Eigen::Vector3d::Zero();  ///< of bias_, rad^2/s^2
};

}  // namespace omnipose::pipeline
