#include "pipeline/gyro_bias.hpp"

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <numbers>

#include "omnipose/so3.hpp"

namespace omnipose::pipeline {
namespace {

/// How fast the readings' scatter follows them, seconds of pairs.
constexpr double kScatterTimeS = 5.0;

/// The variance per IMU axis of a reading (rad^2/s^2): the images' rotation covariance
/// turned into the IMU's axes and the gyro's white noise, over dt^2.
Eigen::Vector3d readingVariance(const GyroBiasReading& r, const Eigen::Matrix3d& camera_from_imu) {
  Eigen::Matrix3d S = r.images_covariance;
  if (!S.allFinite() || !(S.diagonal().minCoeff() > 0.0)) {
    constexpr double kUnknown = GyroBias::kUnknownImagesSigma;
    S = Eigen::Matrix3d::Identity() * (kUnknown * kUnknown);
  }
  const Eigen::Matrix3d imu = camera_from_imu.transpose() * S * camera_from_imu;
  const double white = std::isfinite(r.gyro_variance) ? std::max(r.gyro_variance, 0.0) : 0.0;
  return (imu.diagonal().array() + white) / (r.dt * r.dt);
}

}  // namespace

bool GyroBias::update(const GyroBiasReading& reading, const Eigen::Matrix3d& camera_from_imu) {
  const double dt = reading.dt;
  if (!(dt > 0.0)) return false;
  // The bias this pair shows, IMU axes (the gyro was integrated with bias() removed).
  const Eigen::Vector3d value =
      bias_ -
      (camera_from_imu.transpose() * rotationVector(reading.gyro.transpose() * reading.images)) /
          dt;
  if (!value.allFinite() || !(value.norm() <= kMaxBiasRadS)) return false;
  const Eigen::Vector3d variance = readingVariance(reading, camera_from_imu);
  if (!variance.allFinite() || !(variance.minCoeff() > 0.0)) return false;
  // A bias that walks, in both estimates alike (one may go long without a reading).
  still_.walk(dt);
  moving_.walk(dt);
  Filter& filter = reading.translating ? moving_ : still_;
  const bool used = filter.update(value, variance, dt);
  combine(camera_from_imu);
  return used;
}

void GyroBias::combine(const Eigen::Matrix3d& camera_from_imu) {
  // The moving pairs' estimate, off by up to kDrivingYawSigma about the camera's vertical.
  const Eigen::Vector3d vertical = camera_from_imu.transpose() * Eigen::Vector3d::UnitZ();
  const Eigen::Vector3d moving_variance =
      moving_.variance().array() +
      kDrivingYawSigma * kDrivingYawSigma * vertical.array().square();
  if (!still_.settled() || !moving_.settled()) {
    // One alone: the settled one, or before either has settled the one with more readings.
    const bool still = still_.settled() ||
                       (!moving_.settled() && still_.readings() >= moving_.readings());
    bias_ = still ? still_.estimate() : moving_.estimate();
    variance_ = still ? still_.variance() : moving_variance;
    return;
  }
  const Eigen::Vector3d w_still = still_.variance().cwiseInverse();
  const Eigen::Vector3d w_moving = moving_variance.cwiseInverse();
  variance_ = (w_still + w_moving).cwiseInverse();
  bias_ = variance_.cwiseProduct(w_still.cwiseProduct(still_.estimate()) +
                                 w_moving.cwiseProduct(moving_.estimate()));
}

bool GyroBias::Filter::update(const Eigen::Vector3d& value, const Eigen::Vector3d& variance,
                              double dt) {
  const Eigen::Vector3d error = value - bias_;
  if (readings_ < kWarmUp) {
    const auto i = static_cast<std::size_t>(readings_++);
    first_[i] = value;
    first_weight_[i] = variance.cwiseInverse();
    startFromFirst();
    return true;
  }
  // The reading if it is one: tested against what a pair of the usual variance would
  // scatter (a reading that states a larger variance is not given a wider gate for it),
  // weighed by its own.
  const Eigen::Vector3d usual = variance.cwiseMin(typical_weight_.cwiseInverse());
  const Eigen::Vector3d gate = scale() * usual + variance_;
  if (!((error.array().square() / gate.array()).maxCoeff() <= kGateSigmas * kGateSigmas))
    return false;
  ++readings_;
  const Eigen::Vector3d gain = variance_.cwiseQuotient(scale() * variance + variance_);
  bias_ += gain.cwiseProduct(error);
  variance_ = (Eigen::Vector3d::Ones() - gain).cwiseProduct(variance_);
  const double a = std::min(1.0, dt / kScatterTimeS);
  scatter_ += a * ((error.array().square() / variance.array()).mean() - scatter_);
  typical_weight_ += a * (variance.cwiseInverse() - typical_weight_);
  return true;
}

void GyroBias::Filter::startFromFirst() {
  const auto n = static_cast<std::size_t>(readings_);
  std::array<std::size_t, kWarmUp> order{};
  std::array<double, kWarmUp> normalized{};
  double scatter_sum = 0.0;
  for (int a = 0; a < 3; ++a) {
    for (std::size_t i = 0; i < n; ++i) order[i] = i;
    const auto end = order.begin() + static_cast<std::ptrdiff_t>(n);
    std::sort(order.begin(), end,
              [&](std::size_t i, std::size_t j) { return first_[i](a) < first_[j](a); });
    double total = 0.0;
    for (std::size_t i = 0; i < n; ++i) total += first_weight_[i](a);
    // The weighted median: the first reading at which the weight below reaches half.
    double below = 0.0;
    double median = first_[order[n - 1]](a);
    for (std::size_t k = 0; k < n; ++k) {
      below += first_weight_[order[k]](a);
      if (below >= 0.5 * total) {
        median = first_[order[k]](a);
        break;
      }
    }
    bias_(a) = median;
    // The residuals against their own sigmas, their mean square and their median absolute
    // value.
    double mean_square = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      normalized[i] = std::abs(first_[i](a) - median) * std::sqrt(first_weight_[i](a));
      mean_square += normalized[i] * normalized[i] / static_cast<double>(n);
    }
    const auto middle = normalized.begin() + static_cast<std::ptrdiff_t>(n / 2);
    std::nth_element(normalized.begin(), middle,
                     normalized.begin() + static_cast<std::ptrdiff_t>(n));
    const double sigma = 1.4826 * *middle;  // the MAD's normal-equivalent sigma
    scatter_sum += sigma * sigma;
    // A median is pi/2 times the variance of the mean it stands for; the readings' mean
    // square, not their median, says how far it may be off: people who bend most of the
    // first readings the same way leave a small median deviation.
    variance_(a) = 0.5 * std::numbers::pi * std::max(mean_square, 1.0) / total;
    typical_weight_(a) = total / static_cast<double>(n);
  }
  scatter_ = scatter_sum / 3.0;
  // With the scale itself from few readings, the estimate's error is Student's t with n - 1
  // degrees of freedom, whose variance is (n - 1) / (n - 3) times the normal's.
  if (n > 3) variance_ *= static_cast<double>(n - 1) / static_cast<double>(n - 3);
}

void GyroBias::Filter::walk(double dt) {
  if (readings_ > 0) variance_.array() += kBiasRandomWalk * kBiasRandomWalk * dt;
}

double GyroBias::Filter::scale() const { return std::max(scatter_, 1.0); }

bool GyroBias::settled() const { return still_.settled() || moving_.settled(); }

std::int64_t GyroBias::readings() const { return still_.readings() + moving_.readings(); }

double GyroBias::sigma() const {
  if (!settled()) return std::numeric_limits<double>::infinity();
  return std::sqrt(variance_.mean());
}

}  // namespace omnipose::pipeline
