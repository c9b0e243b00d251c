#include "runtime/worker_count_tuner.hpp"

#include <algorithm>
#include <cmath>

namespace omnipose::runtime {
namespace {

/// Weight of the newest frame in the averages, once a count has run this many frames (before,
/// the plain mean of the frames so far).
constexpr double kAlpha = 0.2;
/// Frames a count runs before its average is trusted enough to probe from it.
constexpr int kWarmUpFrames = 5;

}  // namespace

WorkerCountTuner::WorkerCountTuner(int workers)
    : workers_(std::max(workers, 1)),
      active_(workers_),
      average_(static_cast<std::size_t>(workers_), 0.0),
      frames_(static_cast<std::size_t>(workers_), 0) {}

int WorkerCountTuner::frameEnded(double seconds, double waited_seconds) {
  if (workers_ == 1 || !std::isfinite(seconds) || seconds <= 0.0) return active_;
  const double waited = std::isfinite(waited_seconds)
                            ? std::clamp(waited_seconds / seconds, 0.0, 1.0)
                            : 0.0;
  if (probe_from_ != 0) {
    judgeProbe(seconds, waited);
    return active_;
  }
  const auto i = static_cast<std::size_t>(active_ - 1);
  const double weight = std::max(kAlpha, 1.0 / (frames_[i] + 1));
  average_[i] += weight * (seconds - average_[i]);
  wait_share_ += weight * (waited - wait_share_);
  ++frames_[i];
  fewer_.hold = std::max(fewer_.hold - 1, 0);
  more_.hold = std::max(more_.hold - 1, 0);
  if (frames_[i] < kWarmUpFrames) return active_;
  if (active_ > 1 && fewer_.hold == 0 && wait_share_ > kWaitShare)
    probe(active_ - 1);
  else if (active_ < workers_ && more_.hold == 0)
    probe(active_ + 1);
  return active_;
}

void WorkerCountTuner::probe(int count) {
  probe_from_ = active_;
  active_ = count;
}

void WorkerCountTuner::judgeProbe(double seconds, double waited) {
  const int from = probe_from_;
  probe_from_ = 0;
  Direction& tried = active_ < from ? fewer_ : more_;
  Direction& other = active_ < from ? more_ : fewer_;
  if (seconds < (1.0 - kGain) * average_[static_cast<std::size_t>(from - 1)]) {
    // Kept: the new count's average starts from this frame; the way back waits its turn.
    const auto i = static_cast<std::size_t>(active_ - 1);
    average_[i] = seconds;
    frames_[i] = 1;
    wait_share_ = waited;
    tried.backoff = kMinHoldFrames;
    tried.hold = 0;
    other.hold = std::max(other.hold, other.backoff);
    return;
  }
  active_ = from;
  tried.hold = tried.backoff;
  tried.backoff = std::min(2 * tried.backoff, kMaxHoldFrames);
}

}  // namespace omnipose::runtime
