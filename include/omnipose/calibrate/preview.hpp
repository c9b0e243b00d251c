#pragma once
/// \file preview.hpp
/// A picture to check a lens calibration at a glance: the donut with the fitted edge
/// circles (green, with the edge points that support them), the used ring (red: outer,
/// blue: inner), the centre, the +x (forward) and +y (left) axes and an arrow for the
/// direction in which the azimuth grows; below it the unwrapped panorama(s) with the
/// azimuth ticks and the horizon row, and the text lines of the report.

#include <opencv2/core.hpp>
#include <span>
#include <string>

#include "omnipose/calibrate/ring_detector.hpp"
#include "omnipose/calibration.hpp"

namespace omnipose::calibrate {

/// The panorama of `frame` under `calibration` in colour (CV_8UC3; bilinear, black outside
/// the image), sampled exactly like the Unwrapper: pixel (u, v) at omniPixel(u, v).
cv::Mat unwrapColour(const cv::Mat& frame, const Calibration& calibration);

/// Composite preview (CV_8UC3). `frames` (at least one; the first is drawn as the donut,
/// up to `max_panoramas` are unwrapped), `detection` of the first frame (may be null),
/// `lines` of text printed at the bottom. Throws std::invalid_argument on no frames.
cv::Mat renderPreview(std::span<const cv::Mat> frames, const Calibration& calibration,
                      const RingDetection* detection, std::span<const std::string> lines,
                      int max_panoramas = 2);

}  // namespace omnipose::calibrate
