#include "imu/gyro_buffer.hpp"

#include <algorithm>
#include <cmath>
#include <iterator>

namespace omnipose::imu {

GyroBuffer::GyroBuffer(std::size_t capacity) : capacity_(std::max<std::size_t>(capacity, 16)) {
  samples_.reserve(capacity_);
}

GyroIntake GyroBuffer::push(const GyroSample& sample) {
  if (!std::isfinite(sample.t) || !sample.rate.allFinite()) return GyroIntake::kNotFinite;
  if (!(sample.rate.cwiseAbs().maxCoeff() <= kMaxGyroRate)) return GyroIntake::kTooFast;
  GyroIntake intake = GyroIntake::kAccepted;
  if (!samples_.empty() && !(sample.t > samples_.back().t)) {
    if (!(sample.t < samples_.back().t - kClockJumpS)) return GyroIntake::kOutOfOrder;
    samples_.clear();
    intake = GyroIntake::kClockRestart;
  }
  if (samples_.size() == capacity_) {
    const auto half = static_cast<std::ptrdiff_t>(capacity_ / 2);
    samples_.erase(samples_.begin(), std::next(samples_.begin(), half));  // keeps the capacity
  }
  samples_.push_back(sample);
  return intake;
}

double GyroBuffer::typicalInterval() const {
  constexpr std::size_t kIntervals = 15;
  const std::size_t n = std::min(kIntervals, samples_.size() > 0 ? samples_.size() - 1 : 0);
  if (n == 0) return 0.0;
  std::array<double, kIntervals> d{};
  const std::size_t last = samples_.size() - 1;
  for (std::size_t i = 0; i < n; ++i) d[i] = samples_[last - i].t - samples_[last - i - 1].t;
  const auto middle = d.begin() + static_cast<std::ptrdiff_t>(n / 2);
  std::nth_element(d.begin(), middle, d.begin() + static_cast<std::ptrdiff_t>(n));
  return *middle;
}

}  // namespace omnipose::imu
