#pragma once
/// \file gyro_queue.hpp
/// Gyro samples from the thread that receives them (ImuSubscriber) to the processing thread:
/// a single-producer, single-consumer ring of fixed capacity, lock-free and allocation-free
/// after construction. A sample that finds the ring full is refused (push() false: the
/// producer counts it), never blocks the producer.

#include <atomic>
#include <cstddef>
#include <span>
#include <vector>

#include "omnipose/gyro.hpp"

namespace omnipose::daemon {

class GyroQueue {
 public:
  /// 4096 samples: 4 s of a 1 kHz gyro, far more than the processing thread ever lags.
  static constexpr std::size_t kCapacity = 4096;

  GyroQueue() : ring_(kCapacity) {}

  /// Producer thread only. False when full (the sample is not queued).
  bool push(const GyroSample& sample) {
    const std::size_t head = head_.load(std::memory_order_relaxed);
    if (head - tail_.load(std::memory_order_acquire) == kCapacity) return false;
    ring_[head % kCapacity] = sample;
    head_.store(head + 1, std::memory_order_release);
    return true;
  }

  /// Consumer thread only: moves up to out.size() samples, oldest first, into `out`; returns
  /// how many.
  std::size_t pop(std::span<GyroSample> out) {
    const std::size_t tail = tail_.load(std::memory_order_relaxed);
    const std::size_t available = head_.load(std::memory_order_acquire) - tail;
    const std::size_t n = available < out.size() ? available : out.size();
    for (std::size_t i = 0; i < n; ++i) out[i] = ring_[(tail + i) % kCapacity];
    tail_.store(tail + n, std::memory_order_release);
    return n;
  }

 private:
  std::vector<GyroSample> ring_;
  std::atomic<std::size_t> head_{0};  ///< samples pushed in all
  std::atomic<std::size_t> tail_{0};  ///< samples popped in all
};

}  // namespace omnipose::daemon
