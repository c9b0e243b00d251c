#pragma once
// The unwrap as its definition states it, for tests that check the renderer or the
// Unwrapper against it: panorama pixel (u, v) is the omni image sampled bilinearly at
// Calibration::omniPixel(u, v), one sample per pixel (cv::remap, replicated border).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "omnipose/calibration.hpp"

namespace omnipose::testing {

/// `omni` unwrapped to the calibration's panorama by one bilinear sample per pixel; the
/// result has omni's type.
inline cv::Mat pointSampledUnwrap(const cv::Mat& omni, const Calibration& cal) {
  cv::Mat map_x(cal.panorama.height, cal.panorama.width, CV_32FC1);
  cv::Mat map_y(map_x.size(), CV_32FC1);
  for (int v = 0; v < map_x.rows; ++v) {
    for (int u = 0; u < map_x.cols; ++u) {
      const Eigen::Vector2d p = cal.omniPixel(u, v);
      map_x.at<float>(v, u) = static_cast<float>(p.x());
      map_y.at<float>(v, u) = static_cast<float>(p.y());
    }
  }
  cv::Mat pano;
  cv::remap(omni, pano, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  return pano;
}

}  // namespace omnipose::testing
