/// equirectFromOmni: a real omni image resampled into an equirectangular texture.

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include "omnipose/synth/equirect_from_omni.hpp"

namespace omnipose::synth {
namespace {

constexpr double kPi = std::numbers::pi;

/// Bilinear sample of a CV_32FC1 image at (x, y), pixel centres at integers; NaN when any
/// of the four neighbours is outside the image.
float bilinear(const cv::Mat& image, double x, double y) {
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  if (x0 < 0 || y0 < 0 || x0 + 1 >= image.cols || y0 + 1 >= image.rows) {
    return std::numeric_limits<float>::quiet_NaN();
  }
  const auto ax = static_cast<float>(x - x0), ay = static_cast<float>(y - y0);
  const float* r0 = image.ptr<float>(y0);
  const float* r1 = image.ptr<float>(y0 + 1);
  const float top = r0[x0] + ax * (r0[x0 + 1] - r0[x0]);
  const float bottom = r1[x0] + ax * (r1[x0 + 1] - r1[x0]);
  return top + ay * (bottom - top);
}

}  // namespace

EquirectFromOmni equirectFromOmni(const cv::Mat& omni, const Calibration& calibration,
                                  int width) {
  const OmniLens& lens = calibration.omni;
  if (omni.empty() || omni.cols != lens.image_width || omni.rows != lens.image_height) {
    throw std::invalid_argument("equirectFromOmni: the image is " + std::to_string(omni.cols) +
                                " x " + std::to_string(omni.rows) + ", the calibration's " +
                                std::to_string(lens.image_width) + " x " +
                                std::to_string(lens.image_height));
  }
  if (width < 16 || width > 16384 || width % 2 != 0) {
    throw std::invalid_argument("equirectFromOmni: width " + std::to_string(width) +
                                " is not an even number in [16, 16384]");
  }
  cv::Mat grey;
  if (omni.channels() == 3) {
    cv::cvtColor(omni, grey, cv::COLOR_BGR2GRAY);
  } else if (omni.channels() == 1) {
    grey = omni;
  } else {
    throw std::invalid_argument("equirectFromOmni: the image has " +
                                std::to_string(omni.channels()) + " channels (1 or 3 expected)");
  }
  cv::Mat image;
  grey.convertTo(image, CV_32F);

  const int height = width / 2;
  cv::Mat values(height, width, CV_32FC1);
  EquirectFromOmni result;
  result.seen = cv::Mat::zeros(height, width, CV_8UC1);
  // A texel is seen when its elevation is on the ring (outside it a lens model may fold
  // back onto the ring) and its pixel at least one pixel inside the ring's edges (the
  // bilinear sample then takes nothing from beyond them).
  const auto [e_inner, e_outer] = calibration.ringElevations();
  result.elevation_min = std::min(e_inner, e_outer);
  result.elevation_max = std::max(e_inner, e_outer);
  const double r_min = lens.radius_inner + 1.0, r_max = lens.radius_outer - 1.0;
  cv::parallel_for_(cv::Range(0, height), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y) {
      const double lat = kPi * (0.5 - (y + 0.5) / height);
      if (!(lat >= result.elevation_min && lat <= result.elevation_max)) continue;
      float* out = values.ptr<float>(y);
      std::uint8_t* seen = result.seen.ptr<std::uint8_t>(y);
      for (int x = 0; x < width; ++x) {
        const double lon = 2.0 * kPi * (0.5 - (x + 0.5) / width);
        const Eigen::Vector3d bearing(std::cos(lat) * std::cos(lon), std::cos(lat) * std::sin(lon),
                                      std::sin(lat));
        const auto pixel = calibration.pixelOfBearing(bearing);
        if (!pixel) continue;
        const double r = calibration.ringRadius(pixel->x(), pixel->y());
        if (!(r >= r_min && r <= r_max)) continue;
        if (!lens.mask.empty()) {
          const int mx = static_cast<int>(std::lround(pixel->x()));
          const int my = static_cast<int>(std::lround(pixel->y()));
          if (mx < 0 || my < 0 || mx >= lens.mask.cols || my >= lens.mask.rows ||
              lens.mask.at<std::uint8_t>(my, mx) == 0) {
            continue;
          }
        }
        const float v = bilinear(image, pixel->x(), pixel->y());
        if (std::isnan(v)) continue;
        out[x] = v;
        seen[x] = 255;
      }
    }
  });
  const int seen_count = cv::countNonZero(result.seen);
  if (seen_count == 0) {
    throw std::invalid_argument("equirectFromOmni: the calibration's ring sees no texel of the image");
  }
  result.fill = cv::mean(values, result.seen)[0];
  values.setTo(result.fill, result.seen == 0);
  values.convertTo(result.texture, CV_8U);  // rounds and saturates
  return result;
}

}  // namespace omnipose::synth
