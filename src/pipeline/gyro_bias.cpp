#include "pipeline/gyro_bias.hpp"

#include <algorithm>
#include <cstddef>
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
  if (!error.allFinite() || !((bias_ + error).norm() <= kMaxBiasRadS)) return false;
  if (readings_ < kWarmUp) {
    first_[static_cast<std::size_t>(readings_++)] = bias_ + error;
    startFromFirst();
    return true;
  }
  const double gate = std::max(kGateSigmas * std::sqrt(3.0 * scatter_), kMinGateRadS);
  if (!(error.norm() <= gate)) return false;
  ++readings_;
  const double weight = std::min(1.0, dt / kTimeConstantS);
  scatter_ += weight * (error.squaredNorm() / 3.0 - scatter_);
  bias_ += weight * error;
  return true;
}

void GyroBias::startFromFirst() {
  const auto n = static_cast<std::size_t>(readings_);
  std::array<double, kWarmUp> axis{};
  const auto end = axis.begin() + static_cast<std::ptrdiff_t>(n);
  const auto middle = axis.begin() + static_cast<std::ptrdiff_t>(n / 2);
  double mad_sum = 0.0;
  for (int a = 0; a < 3; ++a) {
    for (std::size_t i = 0; i < n; ++i) axis[i] = first_[i](a);
    std::nth_element(axis.begin(), middle, end);
    double median = *middle;
    if (n % 2 == 0) median = 0.5 * (median + *std::max_element(axis.begin(), middle));
    bias_(a) = median;
    for (std::size_t i = 0; i < n; ++i) axis[i] = std::abs(first_[i](a) - median);
    std::nth_element(axis.begin(), middle, end);
    mad_sum += *middle;
  }
  const double sigma = 1.4826 * mad_sum / 3.0;  // the MAD's normal-equivalent sigma
  scatter_ = sigma * sigma;
}

double GyroBias::sigma() const {
  if (readings_ < 2) return std::numeric_limits<double>::infinity();
  // The readings averaged: all of them while warming up, about 2 tau / dt (at 30 fps) after.
  const double averaged = std::min(static_cast<double>(readings_), 2.0 * kTimeConstantS * 30.0);
  return std::sqrt(scatter_ / averaged);
}

}  // namespace omnipose::pipeline
