#include "pipeline/gyro_bias.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "omnipose/so3.hpp"

namespace omnipose::pipeline {

bool GyroBias::update(const Eigen::Matrix3d& images, const Eigen::Matrix3d& gyro, double dt,
                      const Eigen::Matrix3d& camera_from_imu) {
  if (!(dt > 0.0)) return false;
  // The error of the estimate this pair shows, IMU axes.
  const Eigen::Vector3d error =
      -(camera_from_imu.transpose() * rotationVector(gyro.transpose() * images)) / dt;
  const double limit = readings_ < kWarmUp ? kMaxBiasRadS : kMaxReadingRadS;
  if (!error.allFinite() || !(error.norm() <= limit)) return false;
  ++readings_;
  const double weight = readings_ <= kWarmUp ? 1.0 / static_cast<double>(readings_)
                                             : std::min(1.0, dt / kTimeConstantS);
  scatter_ += weight * (error.squaredNorm() / 3.0 - scatter_);
  bias_ += weight * error;
  return true;
}

double GyroBias::sigma() const {
  if (readings_ < 2) return std::numeric_limits<double>::infinity();
  // The readings averaged: all of them while warming up, about 2 tau / dt (at 30 fps) after.
  const double averaged = std::min(static_cast<double>(readings_), 2.0 * kTimeConstantS * 30.0);
  return std::sqrt(scatter_ / averaged);
}

}  // namespace omnipose::pipeline
