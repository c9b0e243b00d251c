#pragma once
/// \file occluder.hpp
/// A static occluder: what the robot sees of itself in the ring.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "omnipose/calibration.hpp"

namespace omnipose::synth {

/// A mast, body or cable bundle in a fixed sector of the ring: the same textured pattern in
/// every frame, so it stays still while the scene moves (and, unmasked, pulls every window
/// it covers towards zero motion). Omni output only.
struct Occluder {
  double image_angle_deg = 0.0;  ///< centre of the sector, image angle atan2(y - cy, x - cx)
  double width_deg = 40.0;       ///< angular width of the sector, degrees, in (0, 360)

  /// One message per bad field (empty = valid).
  std::vector<std::string> validate() const;
  /// Paints the occluder over a rendered omni image (CV_32FC1, grey 0..255) within the
  /// calibration's ring [radius_inner - 2, radius_outer + 2] px.
  void paint(cv::Mat& image, const Calibration& calibration) const;
  /// The mask that hides it: CV_8UC1 of the frame size, 0 inside the sector widened by
  /// `margin_deg` on each side, 255 elsewhere.
  cv::Mat mask(const Calibration& calibration, double margin_deg = 2.0) const;
};

/// "ANGLE,WIDTH" in degrees; throws std::invalid_argument naming the text otherwise.
Occluder parseOccluder(const std::string& text);

}  // namespace omnipose::synth
