#pragma once
/// \file gyro_fusion.hpp
/// A motion the images measured, combined with the gyro's rotation over the same interval
/// (private to the core library; PipelineOptions::gyro_fusion; DESIGN.md section 3, "The
/// gyro in each pair").
///
/// The fit gives the motion x = (omega, tau) with covariance C (motion_fit.hpp); the gyro,
/// integrated with its estimated bias removed, gives the rotation G with variance q per axis
/// (its white noise over the interval and its bias's uncertainty times the interval). With the
/// images' rotation R perturbed on the right, R exp(d), the gyro measures d = log(R^T G) with
/// noise q I: the update of a Gaussian by a linear measurement of its first three components,
///   K = C[:, omega] (C[omega, omega] + q I)^-1,  x += K log(R^T G),  C -= K C[omega, :],
/// so the rotation moves towards the gyro's by how much less certain the images are, and the
/// translation with it through its correlation with the rotation (a yaw the fit traded for a
/// turn of the direction of travel is traded back).
///
/// Realtime: fixed-size matrices only, no allocation, never throws.

#include <Eigen/Core>

#include "omnipose/motion_fit.hpp"

namespace omnipose::pipeline {

/// A phone-class MEMS gyro's white noise, rad/s/sqrt(Hz) (0.005 deg/s/sqrt(Hz)): used when
/// the calibration's imu section does not give gyro_noise_density.
inline constexpr double kPhoneGyroNoiseDensity = 8.7e-5;

/// The variance per axis of the gyro's rotation over `dt` seconds, rad^2: white noise of
/// `noise_density` (rad/s/sqrt(Hz)) and a bias known to `bias_sigma` (rad/s). Infinity when
/// either is not finite.
double gyroRotationVariance(double noise_density, double bias_sigma, double dt);

/// Replaces `rotation` (the images', from the reference frame to the current one, camera
/// axes) and `estimate`'s tau and covariance by their combination with the gyro's rotation
/// `gyro` (camera axes, same interval) of variance `gyro_variance` per axis (rad^2); omega is
/// set to the combined rotation's vector. False, nothing changed, when the variance is not
/// finite and positive or the estimate's rotation covariance is not positive definite.
bool fuseGyroRotation(Eigen::Matrix3d& rotation, MotionEstimate& estimate,
                      const Eigen::Matrix3d& gyro, double gyro_variance);

}  // namespace omnipose::pipeline
