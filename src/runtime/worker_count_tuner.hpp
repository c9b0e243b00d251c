#pragma once
/// \file worker_count_tuner.hpp
/// How many of a WorkerPool's workers take part in the next frame (private).
///
/// On an idle machine every worker helps. On a shared one a worker may be descheduled while it
/// holds an index, and the caller then waits for it: on a 2-core machine with one busy process
/// at a higher priority than the pipeline, the 2-worker frame took longer than the caller
/// alone (docs/PERFORMANCE.md, "Sharing the cores"). Which count is faster depends on
/// the other processes' load, which the pipeline cannot see, so the tuner measures it: when the
/// caller spent a noticeable share of the recent frames waiting for workers, it tries one
/// worker fewer for one frame and keeps that count if the frame was faster than the current
/// count's recent frames; while below all workers it tries one more now and then, the same way.
/// A probe that loses is not repeated for a while, twice as long after each loss (up to
/// kMaxHoldFrames), so a steady load costs at most one slower frame in that many. Frames are
/// compared by wall time, the whole frame's work (a burst of WorkerPool).
///
/// Pure bookkeeping: no clock, no allocation after construction; one thread (the pool's caller).

#include <vector>

namespace omnipose::runtime {

class WorkerCountTuner {
 public:
  /// Share of a frame's wall time spent waiting for workers, averaged over recent frames, above
  /// which one worker fewer is tried (idle, the pipeline's frames wait ~3 %).
  static constexpr double kWaitShare = 0.10;
  /// A probe's frame is kept when it is this much faster than the current count's average.
  static constexpr double kGain = 0.05;
  /// Frames between a lost probe and the next in the same direction: the first, and the most.
  static constexpr int kMinHoldFrames = 30;
  static constexpr int kMaxHoldFrames = 480;

  /// `workers` >= 1: the pool's size, the caller included; all take part at first.
  explicit WorkerCountTuner(int workers);

  /// Workers to take part in the next frame, the caller included, in [1, workers].
  int active() const { return active_; }

  /// After a frame run with active() workers: its wall time and the time the caller waited for
  /// indices claimed by workers, in seconds. Returns active() for the next frame.
  int frameEnded(double seconds, double waited_seconds);

 private:
  struct Direction {
    int hold = 0;                  ///< frames before the next probe this way is allowed
    /// The hold after the next lost probe this way: kMinHoldFrames after a kept probe, doubled
    /// by each lost one up to kMaxHoldFrames.
    int backoff = kMinHoldFrames;
  };
  /// Starts a one-frame probe of `count` workers.
  void probe(int count);
  /// The probe's frame took `seconds`, `waited` of it waiting: keep its count or go back.
  void judgeProbe(double seconds, double waited);

  int workers_;
  int active_;
  std::vector<double> average_;  ///< recent frame wall time per count (index count - 1); 0 = none
  std::vector<int> frames_;      ///< frames averaged per count
  double wait_share_ = 0.0;      ///< recent share of wall time waited, at the current count
  int probe_from_ = 0;           ///< the count before the probe running now; 0 = no probe
  Direction fewer_, more_;
};

}  // namespace omnipose::runtime
