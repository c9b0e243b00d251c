#pragma once
/// \file imu_estimation.hpp
/// The camera-gyro calibration (calibration.yaml section `imu`: the gyro's mounting and its
/// clock's offset) and the gyro's bias, from a recording of the robot turning and shaking
/// (`omnipose-calibrate --imu-from DATASET`).
///
/// How: the frames are registered once (Odometry, with the calibration's readout), giving
/// each consecutive pair's rotation a_k between the frames' timestamps (rotation vector,
/// camera axes). For a clock offset d the gyro's samples give the same pairs' rotations g_k
/// (integrateGyro, IMU axes, with the bias b taken out). With the mounting X (camera from
/// IMU), a_k = X g_k: X is the rotation that best aligns the g_k with the a_k (Kabsch), b the
/// least-squares bias given X (a few alternations), and the score the mean squared residual
/// |a_k - X g_k|^2. The offset minimises the score: a grid over [-max, max], a finer grid
/// around the best, then the vertex of the parabola through the best and its neighbours.
/// A wrong offset shifts every g_k by the change of rate over a pair times the error, so the
/// recording must change its rates (turn, speed up, slow down, shake) about at least two axes.
///
/// A rolling shutter (the calibration's sensor.readout_s not 0): the images alone measure a
/// pair's rotation poorly when the rate changes within a frame (DESIGN.md section 3), so the
/// first estimate is refined: the frames are registered again with each row's rotation within
/// its frame from the gyro at that estimate, and the clock, mounting and bias found again from
/// those pairs, four times. With the calibration's readout (a datasheet's, or
/// --readout-from's, a few per cent off) a pair's rotation depends on the clock offset plus the
/// mean row's capture time, so the windows' offset comes out off by about half the readout's
/// error. Last, with either shutter, the clock offset, the mounting and a rolling shutter's
/// readout are measured from the pixels with the gyro's rotation (photometric_timing.hpp: every
/// pixel at its own row's time), the mounting held to the pairs' estimate by its uncertainty.
/// When the pixels cannot tell, the calibration's readout and the pairs' clock and mounting
/// stay and pixels_summary says why.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <utility>
#include <vector>

#include "omnipose/calibrate/photometric_timing.hpp"
#include "omnipose/calibrate/readout_estimation.hpp"
#include "omnipose/calibration.hpp"
#include "omnipose/gyro.hpp"
#include "omnipose/odometry.hpp"

namespace omnipose::calibrate {

struct ImuSearchOptions {
  double max_offset_s = 0.1;        ///< largest |time_offset_s| tried, seconds, (0, 1]
  double coarse_step_s = 0.002;     ///< first grid, seconds
  double fine_step_s = 0.0002;      ///< second grid around the best, seconds
  /// Refused when the mounting is less certain than this (1 sigma of its worst axis), degrees.
  double max_rotation_sigma_deg = 0.5;
  /// Refused when the offset is less certain than this (1 sigma), seconds.
  double max_offset_sigma_s = 0.002;
  /// Two samples further apart than this are a gap in the recording: the pairs within
  /// max_offset_s of it are left out, seconds.
  double max_gap_s = 0.05;
  /// How the clock, the mounting and a rolling shutter's readout are measured from the
  /// pixels; its max_gap_s is replaced by the one above.
  PhotometricTimingOptions pixels;
  OdometryOptions odometry = calibrationOdometry();  ///< how the frames are registered

  /// One message per bad field (empty = valid).
  std::vector<std::string> validate() const;
};

struct ImuEstimate {
  bool found = false;
  /// The estimate when found: rotation (camera from IMU) and time_offset_s; the noise
  /// density is not measured (unset).
  ImuCalibration imu;
  Eigen::Vector3d bias = Eigen::Vector3d::Zero();  ///< the gyro's bias, rad/s, IMU axes
  /// How well each is determined (1 sigma, from the residuals): the mounting's worst axis,
  /// degrees; the offset, seconds; the bias per axis, rad/s.
  double rotation_sigma_deg = 0.0;
  double time_offset_sigma_s = 0.0;
  Eigen::Vector3d bias_sigma = Eigen::Vector3d::Zero();
  double residual_rms_rad = 0.0;  ///< per pair, at the estimate
  int pairs = 0;                  ///< consecutive tracked pairs the gyro covers
  /// With a rolling shutter whose readout the pixels measured: the readout (signed as
  /// SensorTiming::readout_s) and its 1 sigma, seconds. 0 when not measured (a global
  /// shutter, or the pixels could not tell).
  double readout_s = 0.0;
  double readout_sigma_s = 0.0;
  /// What the pixels measured (then the mounting, time_offset_s and their sigmas are theirs;
  /// the bias and the residual stay the pairs'), or why they could not.
  std::string pixels_summary;
  /// Why no estimate, or what it rests on, for the user.
  std::string summary;
  /// Every offset tried and its score (mean squared residual, rad^2), in the order tried.
  std::vector<std::pair<double, double>> curve;
};

/// Estimates the camera-gyro calibration from `frames` (as a FrameSource delivers them)
/// captured at `times_s` (seconds on the camera's clock, increasing) through `calibration`
/// (its readout is used, its imu section ignored), and the gyro's `samples` (io/gyro.hpp).
/// Not found (with the reason in summary): fewer than 10 consecutive tracked pairs covered by
/// the samples without a gap, a best offset at the end of the range, a mounting or offset
/// less certain than the options allow (a recording that turns about one axis, or at a steady
/// rate). `exposures_s`: each frame's exposure as its camera reported it (seconds; NaN or
/// empty: the calibration's sensor.exposure_s; FrameStamp::exposure_s). Throws
/// std::invalid_argument on invalid options, a frame count different from the time count (or
/// from a non-empty exposure count), or an invalid calibration.
ImuEstimate estimateImuCalibration(const Calibration& calibration, std::span<const cv::Mat> frames,
                                   std::span<const double> times_s,
                                   std::span<const GyroSample> samples,
                                   const ImuSearchOptions& options = {},
                                   std::span<const double> exposures_s = {});

}  // namespace omnipose::calibrate
