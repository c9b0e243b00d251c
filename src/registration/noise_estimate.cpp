#include "registration/noise_estimate.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace omnipose::registration {
namespace {

/// Median of |N(0, 1)|.
constexpr double kMadToSigma = 0.6744897501960817;

}  // namespace

NoiseEstimator::NoiseEstimator(int width, int top, int rows, const cv::Mat& usable)
    : width_(width) {
  const bool masked = !usable.empty();
  for (int r = top; r + 1 < top + rows; r += 2) {
    for (int c = 0; c + 1 < width; c += 2) {
      if (masked && !(usable.at<float>(r, c) >= 0.999f && usable.at<float>(r, c + 1) >= 0.999f &&
                      usable.at<float>(r + 1, c) >= 0.999f &&
                      usable.at<float>(r + 1, c + 1) >= 0.999f))
        continue;
      block_offsets_.push_back(r * width + c);
    }
  }
  details_.resize(block_offsets_.size());
}

double NoiseEstimator::sigma(const cv::Mat& panorama) {
  const auto* base = panorama.ptr<float>(0);
  const std::size_t stride = panorama.step1();
  std::size_t count = 0;
  for (const int offset : block_offsets_) {
    const std::size_t r = static_cast<std::size_t>(offset / width_);
    const std::size_t c = static_cast<std::size_t>(offset % width_);
    const float* p = base + r * stride + c;
    const float d = 0.5f * std::abs(p[0] - p[1] - p[stride] + p[stride + 1]);
    if (std::isfinite(d)) details_[count++] = d;
  }
  if (count < static_cast<std::size_t>(kMinBlocks)) return std::numeric_limits<double>::quiet_NaN();
  const auto middle = details_.begin() + static_cast<std::ptrdiff_t>(count / 2);
  std::nth_element(details_.begin(), middle, details_.begin() + static_cast<std::ptrdiff_t>(count));
  return *middle / kMadToSigma;
}

}  // namespace omnipose::registration
