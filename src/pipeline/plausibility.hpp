#pragma once
/// \file plausibility.hpp
/// Whether a frame that decoded can be believed (private to the core library; used by
/// Odometry). A glitching camera hands over frames that decode but are not the scene of
/// this moment: a buffer written half by this frame and half by the last one, the same
/// buffer twice, a sensor reset, a frame from another camera, noise. Chained as if they
/// were, they turn the robot for good (one flipped frame: 8-19 degrees).
///
/// Three tests, each on what such a frame cannot hide:
/// - **Repeated rows.** A row of a real sensor is never bit-identical to the same row of
///   the previous frame (sensor noise; a render moves it as soon as the camera moves). When
///   the last pair moved, a frame whose rows with content are more than
///   PlausibilityOptions::max_repeated_rows the previous frame's is a repeated or torn
///   buffer. A camera at rest (the last pair did not move) may repeat: then it is believed.
/// - **Confidence.** The refined pass's windows' median confidence (unmasked windows, an
///   invalid one counting 0; the shift-only first pass's falls with fast roll and pitch,
///   which the refinement takes out) is the height of the phase-correlation peaks above what
///   unrelated content gives: 0-0.04 for a flipped, rotated, foreign or noise frame, 0.12
///   and more for every believed pair of the renders tried (0.3-0.95 mostly; motion blur and
///   a rolling shutter lower it). Below kMinConfidence the pair is not believed; below
///   min_confidence_ratio of the median of the last kHistory believed pairs (from three on)
///   it is not believed either when its fit is not kOk (few windows agree, or a large
///   residual), as a glitch's is and a blurred frame's mostly is not.
/// - **Rotation rate.** A rotation faster than max_rotation_rad_s over the pair's interval
///   (at least kMinRateInterval) is beyond the robot.
///
/// Realtime: the constructor sizes everything; the checks allocate nothing.

#include <array>
#include <cstdint>
#include <opencv2/core.hpp>
#include <span>
#include <vector>

#include "omnipose/error.hpp"
#include "omnipose/motion_fit.hpp"
#include "omnipose/odometry.hpp"
#include "omnipose/window_motion.hpp"

namespace omnipose::pipeline {

class PlausibilityGate {
 public:
  /// Believed pairs whose confidence makes the reference.
  static constexpr int kHistory = 16;
  /// Median window confidence below which nothing is believed (unrelated content gives
  /// 0-0.04; a clean match > 0.8).
  static constexpr double kMinConfidence = 0.05;
  /// A pair that turned or translated more than this (radians; tau in scene distances)
  /// "moved": a repeated frame after it is a glitch.
  static constexpr double kMovedThreshold = 1e-3;
  /// Shortest interval the rotation-rate test divides by, seconds (one frame at 30 fps):
  /// timestamps that bunch frames must not make a turn look fast.
  static constexpr double kMinRateInterval = 1.0 / 30.0;

  /// `frame_rows`: rows of the frames that will be checked (the input frame size);
  /// `windows`: windows per pass.
  PlausibilityGate(const PlausibilityOptions& options, int frame_rows, int windows);

  /// Repeated-rows test of `frame` against the last believed frame (kImplausible naming
  /// the share), and keeps its row hashes as the candidate next reference.
  Expected<void> checkFrame(const cv::Mat& frame);
  /// Confidence test of the windows of the pass that makes the estimate (a refinement) and
  /// of its fit's status; the confidence joins the history if the frame is believed.
  Expected<void> checkConfidence(std::span<const WindowMotion> windows, FitStatus status);
  /// Rotation-rate test: a rotation of `angle_rad` over `interval_s` seconds.
  Expected<void> checkRotation(double angle_rad, double interval_s) const;

  /// The frame checked last was believed: its rows become the reference, its pass's
  /// confidence joins the history; `moved`: its motion (from the last believed frame).
  void believe(bool moved);
  /// It was not: counts a rejection in a row.
  void reject() { ++rejected_in_a_row_; }
  /// Rejections in a row since the last believed frame.
  int rejectedInARow() const { return rejected_in_a_row_; }
  /// A new segment: no history, no reference rows.
  void restart();

  bool enabled() const { return options_.enabled; }

 private:
  /// Median window confidence of `windows` (unmasked ones; an invalid one counts 0).
  double medianConfidence(std::span<const WindowMotion> windows);

  PlausibilityOptions options_;
  std::vector<std::uint64_t> reference_rows_;  ///< hashes of the last believed frame's rows
  std::vector<std::uint64_t> candidate_rows_;  ///< of the frame checked last
  std::vector<std::uint8_t> reference_content_;  ///< 1: that row is not constant
  std::vector<std::uint8_t> candidate_content_;
  bool has_reference_ = false;
  bool reference_moved_ = false;  ///< the pair that made the reference moved
  std::array<double, kHistory> history_{};
  int history_size_ = 0;
  int history_next_ = 0;
  double candidate_confidence_ = -1.0;  ///< of the last checked pass; < 0: none
  std::vector<double> scratch_;        ///< window confidences, sized for the ring
  int rejected_in_a_row_ = 0;
};

}  // namespace omnipose::pipeline
