#include "omnipose/synth/gyro.hpp"

#include <cmath>
#include <random>
#include <stdexcept>

#include "synth/seeding.hpp"

namespace omnipose::synth {

std::vector<std::string> GyroSimulation::validate() const {
  std::vector<std::string> p;
  const auto check = [&](bool ok, const char* field, const char* rule) {
    if (!ok) p.push_back(std::string("gyro.") + field + ": " + rule);
  };
  check(std::isfinite(rate_hz) && rate_hz > 0.0 && rate_hz <= 100000.0, "rate_hz",
        "must be in (0, 100000] Hz");
  check(std::isfinite(noise_density) && noise_density >= 0.0, "noise_density",
        "must be finite and >= 0 rad/s/sqrt(Hz)");
  check(std::isfinite(bias) && bias >= 0.0, "bias", "must be finite and >= 0 rad/s");
  check(std::isfinite(bias_random_walk) && bias_random_walk >= 0.0, "bias_random_walk",
        "must be finite and >= 0 rad/s^2/sqrt(Hz)");
  check(std::isfinite(time_offset_s) && std::abs(time_offset_s) <= 1.0, "time_offset_s",
        "must be within [-1, 1] s");
  check(rotation.coeffs().allFinite() && std::abs(rotation.norm() - 1.0) <= 1e-6, "rotation",
        "must be a unit quaternion");
  return p;
}

GyroRecording simulateGyro(std::span<const StampedPose> trajectory, Interpolation interpolation,
                           const GyroSimulation& gyro, double t_begin, double t_end) {
  if (const auto problems = gyro.validate(); !problems.empty())
    throw std::invalid_argument(problems.front());
  if (trajectory.empty()) throw std::invalid_argument("simulateGyro: empty trajectory");
  if (!(t_end >= t_begin)) throw std::invalid_argument("simulateGyro: t_end before t_begin");
  std::mt19937_64 rng(detail::itemSeed(gyro.seed, 0, /*stream=*/1));
  std::normal_distribution<double> normal;
  const auto gaussian = [&] { return Eigen::Vector3d(normal(rng), normal(rng), normal(rng)); };
  Eigen::Vector3d bias = gaussian();
  bias = bias.norm() > 0.0 ? Eigen::Vector3d(gyro.bias * bias.normalized()) : Eigen::Vector3d::Zero();
  const double interval = 1.0 / gyro.rate_hz;
  const double noise_std = gyro.noise_density * std::sqrt(gyro.rate_hz);
  const double walk_std = gyro.bias_random_walk * std::sqrt(interval);
  const Eigen::Matrix3d imu_from_camera = gyro.rotation.normalized().toRotationMatrix().transpose();
  const double first_stamp = t_begin - gyro.time_offset_s;
  const auto count = static_cast<std::size_t>(std::floor((t_end - t_begin) * gyro.rate_hz)) + 1;
  std::vector<GyroSample> samples;
  samples.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    const double stamp = first_stamp + static_cast<double>(i) * interval;
    const Eigen::Vector3d w =
        angularVelocityAtTime(trajectory, stamp + gyro.time_offset_s, interpolation);
    samples.push_back({stamp, imu_from_camera * w + bias + noise_std * gaussian()});
    bias += walk_std * gaussian();
  }
  return gyroRecordingOf(std::move(samples));
}

}  // namespace omnipose::synth
