#include "map/place_memory.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

namespace omnipose::map {

PlaceSignature::PlaceSignature(cv::Size panorama)
    : width_(panorama.width), height_(panorama.height) {
  if (height_ < kBands || width_ < 2 * kHarmonics + 1)
    throw std::invalid_argument("PlaceSignature: a panorama of " + std::to_string(width_) + " x " +
                                std::to_string(height_) + " pixels is too small");
  const auto size = static_cast<std::size_t>(kHarmonics) * static_cast<std::size_t>(width_);
  cos_.resize(size);
  sin_.resize(size);
  for (int k = 0; k < kHarmonics; ++k) {
    for (int u = 0; u < width_; ++u) {
      const double angle = 2.0 * std::numbers::pi * (k + 1) * u / width_;
      cos_[static_cast<std::size_t>(k * width_ + u)] = std::cos(angle);
      sin_[static_cast<std::size_t>(k * width_ + u)] = std::sin(angle);
    }
  }
  profile_.resize(static_cast<std::size_t>(width_));
}

void PlaceSignature::compute(const cv::Mat& panorama, Vector& out) {
  out.fill(0.0f);
  if (panorama.type() != CV_32FC1 || panorama.cols != width_ || panorama.rows != height_) return;
  double variance = 0.0;  // of the bands' mean rows about their means, summed
  for (int band = 0; band < kBands; ++band) {
    const int v0 = band * height_ / kBands, v1 = (band + 1) * height_ / kBands;
    std::fill(profile_.begin(), profile_.end(), 0.0);
    for (int v = v0; v < v1; ++v) {
      const float* row = panorama.ptr<float>(v);
      for (int u = 0; u < width_; ++u) profile_[static_cast<std::size_t>(u)] += row[u];
    }
    double mean = 0.0;
    for (double& p : profile_) mean += (p /= (v1 - v0));
    mean /= width_;
    for (const double p : profile_) variance += (p - mean) * (p - mean) / width_;
    for (int k = 0; k < kHarmonics; ++k) {
      const double* c = cos_.data() + static_cast<std::size_t>(k * width_);
      const double* s = sin_.data() + static_cast<std::size_t>(k * width_);
      double re = 0.0, im = 0.0;
      for (int u = 0; u < width_; ++u) {
        re += profile_[static_cast<std::size_t>(u)] * c[u];
        im += profile_[static_cast<std::size_t>(u)] * s[u];
      }
      // The square root evens out the harmonics' range (the low ones are much stronger).
      out[static_cast<std::size_t>(band * kHarmonics + k)] =
          static_cast<float>(std::sqrt(std::hypot(re, im) / width_));
    }
  }
  if (!(variance > kMinVariance)) {
    out.fill(0.0f);
    return;
  }
  // Centred and scaled to unit length: similarity() is then the correlation of two
  // signatures, which tells views apart far better than the cosine of all-positive vectors.
  double mean = 0.0;
  for (const float x : out) mean += x;
  mean /= static_cast<double>(out.size());
  double norm2 = 0.0;
  for (float& x : out) {
    x = static_cast<float>(x - mean);
    norm2 += static_cast<double>(x) * x;
  }
  if (!(norm2 > 0.0)) {
    out.fill(0.0f);
    return;
  }
  const auto scale = static_cast<float>(1.0 / std::sqrt(norm2));
  for (float& x : out) x *= scale;
}

double PlaceSignature::similarity(const Vector& a, const Vector& b) {
  double dot = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i) dot += static_cast<double>(a[i]) * b[i];
  return std::clamp(dot, 0.0, 1.0);
}

PlaceMemory::PlaceMemory(int capacity, cv::Size panorama) {
  if (capacity < 1) throw std::invalid_argument("PlaceMemory: capacity must be at least 1");
  places_.resize(static_cast<std::size_t>(capacity));
  for (Place& p : places_) p.panorama = cv::Mat::zeros(panorama, CV_8UC1);
}

void PlaceMemory::store(int id, const cv::Mat& panorama, const PlaceSignature::Vector& signature,
                        std::int64_t sequence, double time_s, double yaw_rate) {
  Place& p = places_[static_cast<std::size_t>(id)];
  if (!p.valid) ++size_;
  p.valid = true;
  panorama.convertTo(p.panorama, CV_8U);  // the same size and type: no allocation
  p.signature = signature;
  p.sequence = sequence;
  p.time_s = time_s;
  p.yaw_rate = yaw_rate;
  p.serial = ++stored_;
  touch(id);
}

void PlaceMemory::restore(int id, const cv::Mat& panorama,
                          const PlaceSignature::Vector& signature, std::int64_t sequence,
                          double time_s, double yaw_rate, long serial, long last_used) {
  Place& p = places_[static_cast<std::size_t>(id)];
  if (!p.valid) ++size_;
  p.valid = true;
  panorama.copyTo(p.panorama);  // the same size and type: no allocation
  p.signature = signature;
  p.sequence = sequence;
  p.time_s = time_s;
  p.yaw_rate = yaw_rate;
  p.serial = serial;
  p.last_used = last_used;
  stored_ = std::max(stored_, serial);
  clock_ = std::max(clock_, last_used);
}

void PlaceMemory::remove(int id) {
  Place& p = places_[static_cast<std::size_t>(id)];
  if (p.valid) --size_;
  p.valid = false;
}

int PlaceMemory::leastRecentlyUsed(int keep_a, int keep_b) const {
  int best = -1;
  for (int id = 0; id < capacity(); ++id) {
    const Place& p = places_[static_cast<std::size_t>(id)];
    if (!p.valid || id == keep_a || id == keep_b) continue;
    if (best < 0 || p.last_used < places_[static_cast<std::size_t>(best)].last_used) best = id;
  }
  return best;
}

void PlaceMemory::clear() {
  for (Place& p : places_) p.valid = false;
  size_ = 0;
  stored_ = 0;
}

}  // namespace omnipose::map
