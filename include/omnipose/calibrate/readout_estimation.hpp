#pragma once
/// \file readout_estimation.hpp
/// The rolling-shutter readout time (calibration.yaml `sensor.readout_s`) from a recording
/// of the robot turning in place at varying rates, for a camera without a datasheet
/// (`omnipose-calibrate --readout-from DATASET`).
///
/// Why it can be measured: a window's rows are captured s_k after the frame's timestamp,
/// s_k = c0 + c1 sin(image angle). While the turn rate changes by b per frame, every window
/// sees the yaw of its own time, X + s_k b, and the sinusoidal part c1 b sin(...) is
/// exactly the pattern a horizontal translation makes (DESIGN.md section 3, "Rolling
/// shutter"). Odometry told a readout r takes out s_k(r) b; what is left, (s_k(r0) - s_k(r))
/// b, shows as translation. A robot turning in place does not translate, so the readout
/// whose estimates translate least is the camera's: the mean squared horizontal tau over
/// the pairs is minimal at r = r0 (quadratic in r - r0).
///
/// The search: that score for readouts on a grid over [-max_s, max_s] (both readout
/// directions), then on a finer grid around the best, then the vertex of the parabola
/// through the best and its two neighbours.

#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/odometry.hpp"

namespace omnipose::calibrate {

/// How the camera's calibration searches register their recordings (estimateReadout() and
/// estimateImuCalibration()): the daemon's defaults, except that each window's depth comes
/// from its own in-window scale at the scale's full weight (MotionFit::Options::
/// plane_depth_prior false), and that each pair's motion is its own registration, not pulled
/// towards a keyframe (KeyframeOptions::slots 0; gaps are bridged against the last good
/// frame), without a map (LoopClosureOptions::enabled false: the searches read the pairs,
/// never the map pose). A calibration recording turns in place, where the scale sees no wall's depth
/// gradient, and the searches read what a wrong readout or clock offset leaves in each
/// pair's fit over that pair's interval: with the scale weighed 0.01, as the plane prior
/// weighs it, --readout-from read the real-camera benchmark's readout 3.8 % short instead of
/// 1.0 %, and --imu-from the clock 0.36 ms off (docs/results/ANALYSIS.md); a pose pulled
/// towards a keyframe mixes in registrations over other intervals.
inline OdometryOptions calibrationOdometry() {
  OdometryOptions o;
  o.pipeline.fit.plane_depth_prior = false;
  o.keyframes.slots = 0;
  o.loop_closure.enabled = false;
  return o;
}

struct ReadoutSearchOptions {
  double max_s = 0.05;         ///< largest |readout_s| tried, seconds, (0, 0.1]
  double coarse_step_s = 0.005;  ///< first grid, seconds
  double fine_step_s = 0.001;    ///< second grid around the best, seconds
  /// The score at the ends of the range must exceed the best by this factor of the best;
  /// a flatter curve says the frames do not show the readout (no change of turn rate, or
  /// too much other motion).
  double min_contrast = 1.0;
  OdometryOptions odometry = calibrationOdometry();  ///< how the frames are registered

  /// One message per bad field (empty = valid).
  std::vector<std::string> validate() const;
};

struct ReadoutEstimate {
  bool found = false;
  double readout_s = 0.0;  ///< the estimate when found, seconds (calibration convention)
  /// Why no estimate, or what it rests on (pairs used, contrast), for the user.
  std::string summary;
  /// Every readout tried and its score (mean squared horizontal tau per pair), in the
  /// order tried.
  std::vector<std::pair<double, double>> curve;
};

/// Estimates sensor.readout_s from `frames` (as a FrameSource delivers them) captured at
/// `times_s` (seconds, increasing) through `calibration` (its own sensor section is ignored).
/// The robot should turn in place, speeding up and slowing down, for at least a few seconds.
/// Not found (with the reason in summary): fewer than 10 frames, fewer than 8 tracked pairs at
/// some readout, a camera that hardly turns (less than 0.1 deg per pair on average: identical
/// frames, a robot standing still), a curve flatter than min_contrast, or a best readout at the
/// end of the range. Throws std::invalid_argument on invalid options, a frame count different
/// from the time count, or an invalid calibration.
ReadoutEstimate estimateReadout(const Calibration& calibration, std::span<const cv::Mat> frames,
                                std::span<const double> times_s,
                                const ReadoutSearchOptions& options = {});

}  // namespace omnipose::calibrate
