#pragma once
/// \file vignetting.hpp
/// Vignetting: the lens' brightness falloff away from its optical centre.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/synth/renderer.hpp"

namespace omnipose::synth {

/// Brightness falloff of the lens away from its optical centre. Omni pixel (x, y) is
/// multiplied by
///   V(x, y) = max(0, 1 - strength * (r / radius_outer)^2),   r = calibration.ringRadius(x, y)
/// (r is the distance from the mirror axis (center_x, center_y) in pixels for the linear
/// lens, the model's ideal radius otherwise), so V = 1 - strength at the ring's outer edge
/// for every lens model and V = 0 where the parabola would go negative (the corners).
/// Panorama pixel (u, v) is multiplied by V at the omni pixel it is unwrapped from,
/// calibration.omniPixel(u, v) (1 where that is undefined): the factor an unwrapped
/// vignetted omni image shows (for the linear lens a function of the row alone).
struct Vignetting {
  double strength = 0.0;  ///< in [0, 1]; 0 = none

  /// One message per bad field (empty = valid).
  std::vector<std::string> validate() const;
  /// V of omni pixel (x, y) (pixel coordinates, x right, y down).
  double factor(const Calibration& calibration, double x, double y) const;
  /// The factor image of an output: CV_32FC1 of the omni image or the panorama size.
  cv::Mat factors(const Calibration& calibration, OutputKind output) const;
  /// Multiplies a rendered image (CV_32FC1 of `output`'s size) by factors(). Throws
  /// std::invalid_argument on an invalid strength or an image of another type or size.
  void apply(cv::Mat& image, const Calibration& calibration, OutputKind output) const;
};

}  // namespace omnipose::synth
