#include "pipeline/ring_alignment.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "omnipose/window_motion.hpp"

namespace omnipose::pipeline {

RingAlignment::RingAlignment(cv::Size panorama)
    : width_(panorama.width),
      height_(panorama.height),
      bins_(panorama.width / 2 + 1),
      input_(static_cast<std::size_t>(panorama.width) * panorama.height),
      surface_(static_cast<std::size_t>(panorama.width) * panorama.height),
      spectrum_(static_cast<std::size_t>(bins_) * panorama.height),
      earlier_(static_cast<std::size_t>(bins_) * panorama.height),
      cross_(static_cast<std::size_t>(bins_) * panorama.height) {
  if (width_ < 4 || height_ < 4)
    throw std::invalid_argument("RingAlignment: needs a panorama of at least 4 x 4");
  taper_.resize(static_cast<std::size_t>(height_));
  for (int v = 0; v < height_; ++v) taper_[v] = static_cast<float>(windowTaper(v, height_));
  forward_ = runtime::FftPlan::realToComplex(height_, width_, input_.data(), spectrum_.data());
  inverse_ = runtime::FftPlan::complexToReal(height_, width_, cross_.data(), surface_.data());
  input_.clear();
  spectrum_.clear();
  cross_.clear();
  surface_.clear();
}

void RingAlignment::whitenedSpectrum(const cv::Mat& panorama, runtime::Complex* out) {
  double sum = 0.0;
  for (int v = 0; v < height_; ++v) {
    const float* row = panorama.ptr<float>(v);
    for (int u = 0; u < width_; ++u) sum += row[u];
  }
  const float mean = static_cast<float>(sum / (static_cast<double>(width_) * height_));
  for (int v = 0; v < height_; ++v) {
    const float* row = panorama.ptr<float>(v);
    float* in = input_.data() + static_cast<std::size_t>(v) * width_;
    for (int u = 0; u < width_; ++u) in[u] = (row[u] - mean) * taper_[v];
  }
  forward_.execute();
  for (std::size_t i = 0; i < spectrum_.size(); ++i) {
    const float magnitude = std::abs(spectrum_[i]);
    out[i] = magnitude > 1e-12f ? spectrum_[i] / magnitude : runtime::Complex{};
  }
}

RingAlignment::Shift RingAlignment::align(const cv::Mat& earlier, const cv::Mat& current) {
  Shift shift;
  whitenedSpectrum(earlier, earlier_.data());
  whitenedSpectrum(current, spectrum_.data());
  // Earlier = current shifted by d: cross = F_earlier conj(F_current) peaks at d.
  for (std::size_t i = 0; i < cross_.size(); ++i) cross_[i] = earlier_[i] * std::conj(spectrum_[i]);
  inverse_.execute();
  std::size_t best = 0;
  for (std::size_t i = 1; i < surface_.size(); ++i)
    if (surface_[i] > surface_[best]) best = i;
  const int row = static_cast<int>(best / static_cast<std::size_t>(width_));
  const int col = static_cast<int>(best % static_cast<std::size_t>(width_));
  const float* r = surface_.data() + static_cast<std::size_t>(row) * width_;
  const double left = r[(col + width_ - 1) % width_], centre = r[col], right = r[(col + 1) % width_];
  const double curvature = left - 2.0 * centre + right;
  const double offset = curvature < 0.0 ? std::clamp(0.5 * (left - right) / curvature, -0.5, 0.5) : 0.0;
  double du = col + offset;
  if (du > 0.5 * width_) du -= width_;
  shift.du_px = du;
  shift.dv_px = row > height_ / 2 ? row - height_ : row;
  shift.peak = centre / (static_cast<double>(width_) * height_);
  return shift;
}

}  // namespace omnipose::pipeline
