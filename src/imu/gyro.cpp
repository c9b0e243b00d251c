#include "omnipose/gyro.hpp"

#include <algorithm>
#include <cmath>

#include "omnipose/calibration.hpp"
#include "omnipose/so3.hpp"

namespace omnipose {
namespace {

/// The rate at IMU time t of the cubic through the samples around piece [a, a + 1] (the
/// Lagrange polynomial through samples a - 1 .. a + 2; the quadratic or the line where the
/// recording ends or a neighbour lies beyond a gap longer than max_gap_s).
Eigen::Vector3d rateAt(std::span<const GyroSample> s, std::size_t a, double t, double max_gap_s) {
  const std::size_t first = a > 0 && s[a].t - s[a - 1].t <= max_gap_s ? a - 1 : a;
  const std::size_t last = a + 2 < s.size() && s[a + 2].t - s[a + 1].t <= max_gap_s ? a + 2 : a + 1;
  Eigen::Vector3d rate = Eigen::Vector3d::Zero();
  for (std::size_t i = first; i <= last; ++i) {
    double weight = 1.0;
    for (std::size_t j = first; j <= last; ++j)
      if (j != i) weight *= (t - s[j].t) / (s[i].t - s[j].t);
    rate += weight * s[i].rate;
  }
  return rate;
}

/// Index of the first sample after IMU time t (samples.size() when none is).
std::size_t firstAfter(std::span<const GyroSample> samples, double t) {
  return static_cast<std::size_t>(
      std::upper_bound(samples.begin(), samples.end(), t,
                       [](double v, const GyroSample& s) { return v < s.t; }) -
      samples.begin());
}

}  // namespace

std::optional<Eigen::Vector3d> gyroRateAt(std::span<const GyroSample> samples,
                                          const ImuCalibration& imu, const Eigen::Vector3d& bias,
                                          double t, double max_gap_s) {
  const double at = t - imu.time_offset_s;
  if (samples.size() < 2 || !(samples.front().t <= at && at <= samples.back().t))
    return std::nullopt;
  // Piece [a, a + 1] holds `at` (the last piece when `at` is the last sample).
  const std::size_t a = std::min(firstAfter(samples, at), samples.size() - 1) - 1;
  if (samples[a + 1].t - samples[a].t > max_gap_s) return std::nullopt;
  const Eigen::Vector3d rate =
      imu.rotation.normalized().toRotationMatrix() * (rateAt(samples, a, at, max_gap_s) - bias);
  if (!rate.allFinite()) return std::nullopt;  // times too far apart for doubles
  return rate;
}

std::optional<Eigen::Matrix3d> integrateGyro(std::span<const GyroSample> samples,
                                             const ImuCalibration& imu,
                                             const Eigen::Vector3d& bias, double t0, double t1,
                                             double max_gap_s) {
  if (t1 < t0) {
    const auto forward = integrateGyro(samples, imu, bias, t1, t0, max_gap_s);
    if (!forward) return std::nullopt;
    return Eigen::Matrix3d(forward->transpose());
  }
  // The interval on the IMU's clock.
  const double begin = t0 - imu.time_offset_s, end = t1 - imu.time_offset_s;
  if (samples.size() < 2 || samples.front().t > begin || samples.back().t < end) return std::nullopt;
  // Sample a is the last at or before `begin` (a + 1 < size: the last is at or after `end`).
  std::size_t a = std::min(firstAfter(samples, begin), samples.size() - 1) - 1;
  const Eigen::Matrix3d camera_from_imu = imu.rotation.normalized().toRotationMatrix();
  // Two-point Gauss-Legendre nodes at the middle -+ this fraction of a piece.
  const double gauss = 0.5 / std::sqrt(3.0);
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  double t = begin;
  while (t < end) {
    if (samples[a + 1].t - samples[a].t > max_gap_s) return std::nullopt;
    const double next = std::min(end, samples[a + 1].t);
    const double h = next - t, middle = 0.5 * (t + next);
    const Eigen::Vector3d w1 = rateAt(samples, a, middle - gauss * h, max_gap_s) - bias;
    const Eigen::Vector3d w2 = rateAt(samples, a, middle + gauss * h, max_gap_s) - bias;
    // Fourth-order Magnus step: the mean rate, and the coning term of a turning axis.
    const Eigen::Vector3d turn = 0.5 * h * (w1 + w2) + (std::sqrt(3.0) / 12.0) * h * h * w1.cross(w2);
    R = R * rotationFromVector(camera_from_imu * turn);
    t = next;
    if (t < end) ++a;
  }
  if (!R.allFinite()) return std::nullopt;  // times too far apart for doubles
  return R;
}

}  // namespace omnipose

namespace omnipose {

std::size_t gyroSamplesArrivedBy(std::span<const GyroSample> samples, const ImuCalibration& imu,
                                 double readout_s, double frame_time) {
  constexpr double kDeliveryS = 0.01;  // the stream's lag after the last row
  const double until = frame_time + std::abs(readout_s) + kDeliveryS - imu.time_offset_s;
  std::size_t n = 0;
  while (n < samples.size() && samples[n].t <= until) ++n;
  return n;
}

}  // namespace omnipose
