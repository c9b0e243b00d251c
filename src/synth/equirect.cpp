#include "synth/equirect.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "common/periodic.hpp"

namespace omnipose::synth::detail {
namespace {

constexpr double kPi = std::numbers::pi;
using ::omnipose::detail::wrapIndex;

/// Binomial [1 3 3 1] / 8 then decimation by 2 along columns (periodic).
cv::Mat halveColumns(const cv::Mat& src) {
  const int w = src.cols / 2;
  cv::Mat dst(src.rows, w, CV_32FC1);
  for (int y = 0; y < src.rows; ++y) {
    const float* s = src.ptr<float>(y);
    float* d = dst.ptr<float>(y);
    for (int i = 0; i < w; ++i) {
      const int c = 2 * i;
      d[i] = (s[wrapIndex(c - 1, src.cols)] + 3.0f * s[c] + 3.0f * s[c + 1] +
              s[wrapIndex(c + 2, src.cols)]) / 8.0f;
    }
  }
  return dst;
}

/// Binomial [1 3 3 1] / 8 then decimation by 2 along rows (clamped at the poles).
cv::Mat halveRows(const cv::Mat& src) {
  const int h = src.rows / 2;
  cv::Mat dst(h, src.cols, CV_32FC1);
  for (int i = 0; i < h; ++i) {
    const int r = 2 * i;
    const float* a = src.ptr<float>(std::max(r - 1, 0));
    const float* b = src.ptr<float>(r);
    const float* c = src.ptr<float>(r + 1);
    const float* e = src.ptr<float>(std::min(r + 2, src.rows - 1));
    float* d = dst.ptr<float>(i);
    for (int x = 0; x < src.cols; ++x) d[x] = (a[x] + 3.0f * b[x] + 3.0f * c[x] + e[x]) / 8.0f;
  }
  return dst;
}

/// Bilinear lookup at fractional texture coordinates (fx, fy) in [0, 1].
float bilinear(const cv::Mat& level, double fx, double fy) {
  const double x = fx * level.cols - 0.5, y = fy * level.rows - 0.5;
  const double xf = std::floor(x), yf = std::floor(y);
  const float ax = static_cast<float>(x - xf), ay = static_cast<float>(y - yf);
  const int x0 = wrapIndex(static_cast<int>(xf), level.cols), x1 = wrapIndex(x0 + 1, level.cols);
  const int y0 = std::clamp(static_cast<int>(yf), 0, level.rows - 1);
  const int y1 = std::clamp(static_cast<int>(yf) + 1, 0, level.rows - 1);
  const float* r0 = level.ptr<float>(y0);
  const float* r1 = level.ptr<float>(y1);
  const float top = r0[x0] + ax * (r0[x1] - r0[x0]);
  const float bottom = r1[x0] + ax * (r1[x1] - r1[x0]);
  return top + ay * (bottom - top);
}

}  // namespace

std::vector<cv::Mat> buildPyramid(const cv::Mat& texture) {
  std::vector<cv::Mat> pyramid{texture};
  for (;;) {
    const cv::Mat& last = pyramid.back();
    if (last.cols % 2 != 0 || last.rows % 2 != 0 || last.cols < 4 || last.rows < 4) break;
    pyramid.push_back(halveRows(halveColumns(last)));
  }
  return pyramid;
}

double texelAngle(const std::vector<cv::Mat>& pyramid) { return kPi / pyramid.front().rows; }

float sampleEquirect(const std::vector<cv::Mat>& pyramid, const Eigen::Vector3d& d, double lod) {
  // Longitude/latitude of the direction, then the fractional texture coordinates.
  const double lon = std::atan2(d.y(), d.x());
  const double lat = std::atan2(d.z(), std::hypot(d.x(), d.y()));
  const double fx = 0.5 - lon / (2.0 * kPi);
  const double fy = 0.5 - lat / kPi;
  const double max_level = static_cast<double>(pyramid.size() - 1);
  const double l = std::clamp(lod, 0.0, max_level);
  const int l0 = static_cast<int>(l);
  const float a = static_cast<float>(l - l0);
  const float v0 = bilinear(pyramid[l0], fx, fy);
  if (a == 0.0f) return v0;
  return v0 + a * (bilinear(pyramid[l0 + 1], fx, fy) - v0);
}

}  // namespace omnipose::synth::detail
