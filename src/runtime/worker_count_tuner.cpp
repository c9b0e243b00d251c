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

}  // namespace

WorkerCountTuner::WorkerCountTuner(int workers)
    : workers_(std::max(workers, 1)), current_(workers_), active_(workers_) {}

int WorkerCountTuner::frameEnded(double seconds) {
  if (workers_ == 1 || !std::isfinite(seconds) || seconds <= 0.0) return active_;
  if (candidate_ != 0) {
    probeFrame(seconds);
    return active_;
  }
  recent_[static_cast<std::size_t>(frames_ % kRecentFrames)] = seconds;
  ++frames_;
  fewer_.hold = std::max(fewer_.hold - 1, 0);
  more_.hold = std::max(more_.hold - 1, 0);
  if (frames_ < kRecentFrames) return active_;
  const double level = median(recent_);
  if (reference_ == 0.0) {
    reference_ = level;
  } else if (std::abs(level - reference_) > kShift * reference_) {
    // The load (or the scene) changed since the last decision: what lost may win now.
    fewer_ = Direction{};
    more_ = Direction{};
    reference_ = level;
  }
  if (current_ > 1 && fewer_.hold == 0)
    startProbe(current_ - 1);
  else if (current_ < workers_ && more_.hold == 0)
    startProbe(current_ + 1);
  return active_;
}

void WorkerCountTuner::startProbe(int count) {
  candidate_ = count;
  probe_frame_ = 0;
  active_ = count;  // the probe's frames alternate, the candidate's first
}

void WorkerCountTuner::probeFrame(double seconds) {
  const int pair = probe_frame_ / 2;
  if (probe_frame_ % 2 == 0)
    candidate_times_[static_cast<std::size_t>(pair)] = seconds;
  else
    current_times_[static_cast<std::size_t>(pair)] = seconds;
  ++probe_frame_;
  if (probe_frame_ == 2 * kProbeFrames) {
    judgeProbe();
    return;
  }
  active_ = probe_frame_ % 2 == 0 ? candidate_ : current_;
}

void WorkerCountTuner::judgeProbe() {
  const int candidate = candidate_;
  candidate_ = 0;
  Direction& tried = candidate < current_ ? fewer_ : more_;
  Direction& other = candidate < current_ ? more_ : fewer_;
  if (median(candidate_times_) < (1.0 - kGain) * median(current_times_)) {
    // Kept: the same way may be tried again at once; the way back waits its turn.
    current_ = candidate;
    restartRecent();
    tried.backoff = kMinHoldFrames;
    tried.hold = 0;
    other.hold = std::max(other.hold, other.backoff);
  } else {
    tried.hold = tried.backoff;
    tried.backoff = std::min(2 * tried.backoff, kMaxHoldFrames);
    if (frames_ >= kRecentFrames) reference_ = median(recent_);
  }
  active_ = current_;
}

void WorkerCountTuner::restartRecent() {
  frames_ = 0;
  reference_ = 0.0;
}

}  // namespace omnipose::runtime
