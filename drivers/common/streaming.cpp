#include "common/streaming.hpp"

#include <algorithm>
#include <cmath>

#include "common/clock_offset.hpp"
#include "omnipose/limits.hpp"

namespace omnipose::drivers {

void appendStreamRequestProblems(std::vector<std::string>& problems, int width, int height,
                                 double fps) {
  constexpr int kMax = limits::kMaxImageSide;
  const std::string range = "must be in [1, " + std::to_string(kMax) + "], is ";
  if (width <= 0 || width > kMax)
    problems.push_back("source.width: " + range + std::to_string(width));
  if (height <= 0 || height > kMax)
    problems.push_back("source.height: " + range + std::to_string(height));
  if (!(fps > 0.0 && fps <= 1000.0))  // also NaN
    problems.push_back("source.fps: must be in (0, 1000]");
}

void appendClockProblems(std::vector<std::string>& problems,
                         std::chrono::milliseconds clock_resync, int clock_samples) {
  if (clock_resync.count() < 1) problems.push_back("clock_resync: must be >= 1 ms");
  if (clock_samples < 1 || clock_samples > kMaxClockSamples)
    problems.push_back("clock_samples: must be in [1, " + std::to_string(kMaxClockSamples) +
                       "], is " + std::to_string(clock_samples));
}

std::uint32_t SequenceTracker::completed(std::uint32_t driver_sequence) {
  std::uint32_t lost = 0;
  if (have_completed_) {
    const std::uint32_t step = driver_sequence - last_completed_;
    if (step >= 1) lost = step - 1;
  }
  have_completed_ = true;
  last_completed_ = driver_sequence;
  return lost;
}

std::uint64_t SequenceTracker::delivered(std::uint32_t driver_sequence,
                                         std::int64_t capture_time_us, double fps) {
  if (!have_sequence_) {
    sequence_ = driver_sequence;
    have_sequence_ = true;
  } else if (restarted_) {
    std::uint64_t gap = 1;
    if (fps > 0 && capture_time_us > last_capture_us_)
      gap = std::max<std::uint64_t>(
          1, static_cast<std::uint64_t>(std::llround(
                 static_cast<double>(capture_time_us - last_capture_us_) * 1e-6 * fps)));
    sequence_ += gap;
  } else {
    sequence_ += static_cast<std::uint32_t>(driver_sequence - last_delivered_driver_);
  }
  restarted_ = false;
  last_delivered_driver_ = driver_sequence;
  last_capture_us_ = capture_time_us;
  return sequence_;
}

}  // namespace omnipose::drivers
