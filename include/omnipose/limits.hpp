#pragma once
/// \file limits.hpp
/// Upper bounds on every size read from a file (calibration.yaml, calib_results.txt, the
/// omnidir file, daemon.yaml). A value beyond them is a start-up error naming the field,
/// never an allocation attempt.

namespace omnipose::limits {

/// Largest frame side, pixels (a 16k camera frame).
inline constexpr int kMaxImageSide = 16384;
/// Largest panorama width, pixels (0.022 degrees per pixel).
inline constexpr int kMaxPanoramaWidth = 16384;
/// Largest panorama height, pixels.
inline constexpr int kMaxPanoramaHeight = 4096;
/// Most coefficients of an OCamCalib polynomial (OCamCalib itself writes at most ~20).
inline constexpr int kMaxPolynomialTerms = 32;

}  // namespace omnipose::limits
