#pragma once
/// \file worker_count_tuner.hpp
/// How many of a WorkerPool's workers take part in the next frame (private).
///
/// On an idle machine every worker helps. On a shared one more workers can make the frame
/// slower: a worker descheduled while it holds an index makes the caller wait, and a worker
/// spinning between jobs takes CPU time from the caller when the process gets fewer cores than
/// it has workers (docs/PERFORMANCE.md, "Sharing the cores"). Which count is faster depends on
/// the other processes' load, which the pipeline cannot see, so the tuner measures it: now and
/// then it runs a probe, kProbeFrames frames on one worker fewer (or more) alternating with as
/// many on the current count, and keeps the other count when the median of its frames is at
/// least kGain faster than the median of the current count's. Alternating frames see the same
/// load and nearly the same content, and the medians ignore one odd frame on either side.
/// A probe that loses is not repeated for a while, twice as long after each loss (from
/// kMinHoldFrames up to kMaxHoldFrames), so a steady load costs at most kProbeFrames slower
/// frames in kMaxHoldFrames. When the current count's frames (the median of the last
/// kRecentFrames) become kShift slower or faster than they were at the last decision (the load
/// changed, or the scene), the waits are cleared and both ways are probed again at once. Frames are compared by wall time, the whole
/// frame's work (a burst of WorkerPool).
///
/// Pure bookkeeping: no clock, no allocation after construction; one thread (the pool's caller).

#include <array>

namespace omnipose::runtime {

class WorkerCountTuner {
 public:
  /// A probe's count is kept when the median of its frames is this much faster.
  static constexpr double kGain = 0.05;
  /// Frames of each count in one probe (the probe is twice as many frames, alternating).
  static constexpr int kProbeFrames = 3;
  /// Frames between a lost probe and the next in the same direction: the first, and the most.
  static constexpr int kMinHoldFrames = 30;
  static constexpr int kMaxHoldFrames = 480;
  /// Relative change of the current count's recent frame time that clears the waits.
  static constexpr double kShift = 0.25;
  /// Frames of the current count whose median is its recent frame time (also the frames it
  /// runs before it is probed from).
  static constexpr int kRecentFrames = 5;

  /// `workers` >= 1: the pool's size, the caller included; all take part at first.
  explicit WorkerCountTuner(int workers);

  /// Workers to take part in the next frame, the caller included, in [1, workers].
  int active() const { return active_; }
  /// The count the frames run on outside probes.
  int current() const { return current_; }

  /// After a frame run with active() workers: its wall time in seconds (frames without a
  /// positive, finite time are ignored). Returns active() for the next frame.
  int frameEnded(double seconds);

 private:
  struct Direction {
    int hold = 0;                  ///< frames before the next probe this way is allowed
    /// The hold after the next lost probe this way: kMinHoldFrames after a kept probe, doubled
    /// by each lost one up to kMaxHoldFrames.
    int backoff = kMinHoldFrames;
  };
  /// Starts a probe of `count` workers against the current count.
  void startProbe(int count);
  /// Records one frame of the probe; judges it after its last frame.
  void probeFrame(double seconds);
  /// The probe is over: keep its count when it was faster, else go back and wait.
  void judgeProbe();
  /// A new count: its recent frames start again.
  void restartRecent();

  int workers_;
  int current_;
  int active_;
  int candidate_ = 0;  ///< the probe's count; 0 = no probe running
  int probe_frame_ = 0;  ///< frames of the running probe so far
  std::array<double, kProbeFrames> candidate_times_{}, current_times_{};
  std::array<double, kRecentFrames> recent_{};  ///< the current count's last frames (a ring)
  int frames_ = 0;          ///< frames run on the current count outside probes
  double reference_ = 0.0;  ///< the recent frame time at the last decision; 0 = not yet set
  Direction fewer_, more_;
};

}  // namespace omnipose::runtime
