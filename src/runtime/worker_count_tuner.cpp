#include "runtime/worker_count_tuner.hpp"

#include <algorithm>
#include <cmath>

namespace omnipose::runtime {
namespace {

template <std::size_t N>
double median(std::array<double, N> values) {
  const auto middle = values.begin() + values.size() / 2;
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

/// The mean of the middle half: robust to an odd frame or two, and steady when the frame times
/// take two values (a frame one of whose cores another process took for a while, and one whose
/// cores it did not take), where a median jumps between them.
template <std::size_t N>
double middleMean(std::array<double, N> values) {
  std::sort(values.begin(), values.end());
  const std::size_t quarter = N / 4;
  double sum = 0.0;
  for (std::size_t i = quarter; i < N - quarter; ++i) sum += values[i];
  return sum / static_cast<double>(N - 2 * quarter);
}

}  // namespace

WorkerCountTuner::WorkerCountTuner(int workers)
    : workers_(std::max(workers, 1)),
      current_{workers_, true},
      active_(current_) {}

PoolSetting WorkerCountTuner::neighbour(Way way) const {
  PoolSetting s = current_;
  switch (way) {
    case kFewer: --s.workers; break;
    case kMore: ++s.workers; break;
    default: s.spin = !s.spin; break;
  }
  // One worker is the caller alone: how workers wait does not matter there, it is one setting.
  if (s.workers < 1 || s.workers > workers_ || (way == kOtherWait && s.workers == 1))
    return PoolSetting{0, true};
  if (s.workers == 1) s.spin = true;
  return s;
}

PoolSetting WorkerCountTuner::frameEnded(double seconds) {
  if (workers_ == 1 || !std::isfinite(seconds) || seconds <= 0.0) return active_;
  if (probing_ >= 0) {
    probeFrame(seconds);
    return active_;
  }
  recent_[static_cast<std::size_t>(frames_ % kRecentFrames)] = seconds;
  ++frames_;
  for (Direction& way : ways_) way.hold = std::max(way.hold - 1, 0);
  if (frames_ < kRecentFrames) return active_;
  const double level = middleMean(recent_);
  if (reference_ == 0.0) reference_ = level;
  shifted_frames_ = std::abs(level - reference_) > kShift * reference_ ? shifted_frames_ + 1 : 0;
  if (shifted_frames_ >= kShiftFrames) {
    // The load (or the scene) changed since the last decision: what lost may win now.
    ways_.fill(Direction{});
    reference_ = level;
    shifted_frames_ = 0;
  }
  for (int way = 0; way < kWays; ++way) {
    const PoolSetting next = neighbour(static_cast<Way>(way));
    if (next.workers == 0 || ways_[static_cast<std::size_t>(way)].hold > 0) continue;
    probing_ = way;
    candidate_ = next;
    probe_frame_ = 0;
    active_ = next;  // the probe's frames alternate, the candidate's first
    break;
  }
  return active_;
}

void WorkerCountTuner::probeFrame(double seconds) {
  const auto pair = static_cast<std::size_t>(probe_frame_ / 2);
  (probe_frame_ % 2 == 0 ? candidate_times_ : current_times_)[pair] = seconds;
  ++probe_frame_;
  if (probe_frame_ == 2 * kProbeFrames)
    judgeProbe();
  else
    active_ = probe_frame_ % 2 == 0 ? candidate_ : current_;
}

void WorkerCountTuner::judgeProbe() {
  Direction& tried = ways_[static_cast<std::size_t>(probing_)];
  const int way = probing_;
  probing_ = -1;
  // Faster in its median and in all but one of the probe's pairs of neighbouring frames.
  int pairs_won = 0;
  for (std::size_t i = 0; i < candidate_times_.size(); ++i)
    if (candidate_times_[i] < (1.0 - kGain) * current_times_[i]) ++pairs_won;
  if (pairs_won >= kProbeFrames - 1 &&
      median(candidate_times_) < (1.0 - kGain) * median(current_times_)) {
    // Kept: the same way may be tried again at once; the way back waits its turn.
    current_ = candidate_;
    frames_ = 0;
    reference_ = 0.0;
    shifted_frames_ = 0;
    tried = Direction{};
    if (way != kOtherWait) {
      Direction& back = ways_[way == kFewer ? kMore : kFewer];
      back.hold = std::max(back.hold, back.backoff);
    } else {
      tried.hold = tried.backoff;  // the way back is this one
    }
  } else {
    tried.hold = tried.backoff;
    tried.backoff = std::min(2 * tried.backoff, kMaxHoldFrames);
    if (frames_ >= kRecentFrames) reference_ = middleMean(recent_);
  }
  active_ = current_;
}

}  // namespace omnipose::runtime
