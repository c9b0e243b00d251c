#pragma once
/// \file photometric_timing.hpp
/// The gyro's clock offset and mounting, and a rolling shutter's readout, measured from the
/// pixels themselves with the gyro's rotation (`omnipose-calibrate --imu-from`, after the
/// pairs' rotations gave a first mounting, clock and bias: imu_estimation.hpp).
///
/// Why the pixels: registering windows (readout_estimation.hpp, the first estimate of
/// imu_estimation.hpp) gives each window one capture time, the mean of its rows' times, while
/// its correlation weighs its pixels by their texture. Where the texture lies unevenly within
/// the windows the two differ, and the readout and the offset come out a little off
/// (docs/results/ANALYSIS.md, "The readout, the clock and the mounting from the pixels").
/// Here every pixel keeps its own row's time, so no texture can bias them; and a pair's
/// rotation is measured by every pixel, not by the fit of a few dozen windows.
///
/// How: for the robot turning in place (its translation between two frames small against the
/// scene's distance), pixel p of frame k+1, exposed at row time s1 = t_{k+1} + rowTime(p),
/// sees bearing b; at time s0 the camera saw it along R(s0, s1) b, the gyro's rotation
/// between the two instants (integrateGyro's convention), which lands at pixel q of frame k,
/// with s0 = t_k + rowTime(q) (three fixed-point steps). The readout (a rolling shutter's
/// only), the offset and a small correction of the mounting minimise
/// sum |I_{k+1}(p) - I_k(q)|^2 over the strongest-gradient pixels of the ring (frames
/// smoothed, each normalised to zero mean and unit variance over the ring against exposure
/// changes; Huber weights against what moves by itself), by Gauss-Newton: the residuals'
/// derivatives are the image gradient at q times the derivatives of q (finite differences
/// of the geometry, which is smooth). The uncertainty treats pairs, not pixels, as
/// independent (neighbouring pixels share noise and interpolation error): the sandwich
/// H^-1 (sum_k g_k g_k^T) H^-1 of the pairs' gradients g_k.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core.hpp>

#include <span>
#include <string>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/gyro.hpp"

namespace omnipose::calibrate {

struct PhotometricTimingOptions {
  int pixels_per_frame = 8000;   ///< strongest-gradient ring pixels used per frame, > 0
  double blur_sigma_px = 1.0;    ///< Gaussian smoothing of the frames, pixels, >= 0
  int max_iterations = 10;       ///< Gauss-Newton steps, > 0
  /// Residuals beyond this many robust sigmas (1.4826 MAD) weigh less (Huber), > 0.
  double huber_sigmas = 2.0;
  double max_gap_s = 0.05;       ///< longer intervals between gyro samples are gaps, seconds
  /// Refused when the readout is less certain than this (1 sigma), as a fraction of it.
  double max_readout_sigma = 0.01;
  /// Refused when the offset is less certain than this (1 sigma), seconds.
  double max_offset_sigma_s = 0.0005;

  /// One message per bad field (empty = valid).
  std::vector<std::string> validate() const;
};

struct PhotometricTiming {
  bool found = false;
  double readout_s = 0.0;            ///< signed as SensorTiming::readout_s; 0 global shutter
  double time_offset_s = 0.0;        ///< as ImuCalibration::time_offset_s
  double readout_sigma_s = 0.0;      ///< 1 sigma, seconds
  double time_offset_sigma_s = 0.0;  ///< 1 sigma, seconds
  double correlation = 0.0;          ///< between the two estimates' errors
  /// The mounting (camera from IMU) corrected by the pixels, how far they moved it and its
  /// worst axis's 1 sigma, degrees.
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  double rotation_change_deg = 0.0;
  double rotation_sigma_deg = 0.0;
  int pairs = 0;                     ///< consecutive frame pairs the gyro covers
  int iterations = 0;                ///< Gauss-Newton steps taken
  double residual_rms = 0.0;         ///< per pixel, of the normalised frames, at the estimate
  std::string summary;               ///< why not found, or what it rests on
};

/// Refines `calibration.imu->time_offset_s` and, with a rolling shutter,
/// `calibration.sensor.readout_s` (roughly known, from a datasheet or --readout-from, within
/// about 10 %; 0, a global shutter, stays 0) from consecutive `frames` captured at `times_s`
/// (seconds, camera clock, increasing) and the gyro's `samples` less `bias` (rad/s, IMU axes).
/// The mounting `calibration.imu->rotation` is corrected too, held to it with a prior of
/// `mounting_sigma_rad` per axis (radians, > 0: how well the pairs' rotations knew it), so
/// that a recording turning about one axis leaves it where it was. `frames`: omni images of
/// the calibration's size (any depth; gray, BGR or BGRA).
/// Not found (summary says why): a frame of another size, fewer than 10 pairs the gyro covers
/// without a gap, too few usable pixels, or estimates less certain than the options allow (a
/// recording whose rate of turn hardly changes within a frame; a steady turn, for the clock;
/// a camera that translates against a near scene, driving instead of turning in place).
/// Throws std::invalid_argument on invalid options, a calibration without an imu section, a
/// mounting_sigma_rad not > 0, or mismatched counts.
PhotometricTiming refineTimingFromPixels(const Calibration& calibration,
                                         std::span<const cv::Mat> frames,
                                         std::span<const double> times_s,
                                         std::span<const GyroSample> samples,
                                         const Eigen::Vector3d& bias, double mounting_sigma_rad,
                                         const PhotometricTimingOptions& options = {});

}  // namespace omnipose::calibrate
