#pragma once
/// \file gyro.hpp
/// A MEMS gyro fixed to the camera, driven by the renderer's exact motion: what `imu.csv`
/// of a rendered dataset holds (io/gyro.hpp).

#include <Eigen/Geometry>

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "omnipose/io/gyro.hpp"
#include "omnipose/io/trajectory.hpp"
#include "omnipose/synth/renderer.hpp"

namespace omnipose::synth {

/// The gyro's rate, errors and mounting. Defaults: a 200 Hz phone-class MEMS gyro.
///
/// Sample i is stamped t_i = t_first + i / rate_hz on the IMU's clock and taken at camera
/// time t_i + time_offset_s (the convention of calibration.yaml's imu.time_offset_s). It
/// measures the camera's angular velocity w(t) (angularVelocityAtTime, camera axes) in the
/// IMU's axes, with a bias and white noise:
///   sample_i = R_camera_imu^T w(t_i + time_offset_s) + b_i + n_i,
/// n_i ~ N(0, noise_density^2 rate_hz I) (the density sampled at rate_hz), b_0 of length
/// `bias` in a direction drawn from `seed`, b_{i+1} = b_i + bias_random_walk sqrt(1 / rate_hz)
/// N(0, I). An instantaneous rate: the sensor's own low-pass filter is not modelled.
struct GyroSimulation {
  double rate_hz = 200.0;              ///< samples per second, (0, 100000]
  double noise_density = 8.7e-5;       ///< white rate noise, rad/s/sqrt(Hz) (0.005 deg/s/sqrt(Hz))
  double bias = 0.0087;                ///< length of the initial bias, rad/s (0.5 deg/s)
  double bias_random_walk = 0.0;       ///< rad/s^2/sqrt(Hz)
  double time_offset_s = 0.0;          ///< camera time of a sample = its stamp + this, |.| <= 1 s
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();  ///< camera from IMU, unit
  std::uint64_t seed = 0;              ///< noise, bias direction and walk

  /// One message per bad field (empty = valid), each starting with "gyro.<field>": every
  /// number finite, rate_hz in (0, 100000], noise_density, bias and bias_random_walk >= 0,
  /// |time_offset_s| <= 1, rotation of norm 1 within 1e-6.
  std::vector<std::string> validate() const;
};

/// The samples of a gyro on the camera moving along `trajectory` (interpolated as the
/// renderer draws it), stamped from camera time t_begin - time_offset_s to the last stamp
/// whose camera time is at most t_end. Throws std::invalid_argument naming the field for an
/// invalid `gyro`, or when t_end < t_begin or the trajectory is empty.
GyroRecording simulateGyro(std::span<const StampedPose> trajectory, Interpolation interpolation,
                           const GyroSimulation& gyro, double t_begin, double t_end);

}  // namespace omnipose::synth
