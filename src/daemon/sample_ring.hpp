#pragma once
/// \file sample_ring.hpp
/// The last N samples of a quantity (processing time, latency) in a fixed ring, with
/// percentiles by selection on a fixed scratch copy. Allocation-free; not thread-safe (one
/// owner thread).

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>

namespace omnipose::daemon {

template <std::size_t N>
class SampleRing {
 public:
  static_assert(N > 0);

  void add(float value) {
    samples_[head_] = value;
    head_ = (head_ + 1) % N;
    if (count_ < N) ++count_;
  }
  std::size_t size() const { return count_; }
  void clear() { head_ = count_ = 0; }

  /// The p-quantile (p in [0, 1], nearest rank) of the stored samples; 0 when empty.
  float percentile(double p) {
    if (count_ == 0) return 0.0f;
    std::copy_n(samples_.begin(), count_, scratch_.begin());
    const double clamped = std::clamp(p, 0.0, 1.0);
    // Nearest rank: the smallest value with at least p * n samples at or below it.
    std::size_t rank = static_cast<std::size_t>(std::ceil(clamped * static_cast<double>(count_)));
    rank = std::clamp<std::size_t>(rank, 1, count_) - 1;
    std::nth_element(scratch_.begin(), scratch_.begin() + static_cast<std::ptrdiff_t>(rank),
                     scratch_.begin() + static_cast<std::ptrdiff_t>(count_));
    return scratch_[rank];
  }

 private:
  std::array<float, N> samples_{};
  std::array<float, N> scratch_{};
  std::size_t head_ = 0;
  std::size_t count_ = 0;
};

}  // namespace omnipose::daemon
