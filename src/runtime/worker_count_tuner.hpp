#pragma once
/// \file worker_count_tuner.hpp
/// How a WorkerPool runs the next frame (private): how many workers take part, and whether
/// they spin between the frame's jobs or sleep.
///
/// On an idle machine every worker helps, and spinning between jobs saves a futex wake-up per
/// job. On a shared one both can make the frame slower: a worker descheduled while it holds an
/// index makes the caller wait, and a worker spinning between jobs takes CPU time the caller
/// needs when the process gets fewer cores than it has threads (docs/PERFORMANCE.md, "Sharing
/// the cores"). Which setting is faster depends on the other processes' load, which the pipeline
/// cannot see, so the tuner measures it. Now and then it runs a probe: kProbeFrames frames of
/// a neighbouring setting (one worker fewer, one more, or the other way of waiting) alternating
/// with as many of the current one, and keeps the neighbour when the median of its frames is at
/// least kGain faster, and so was its frame in all but one of the probe's pairs of neighbouring
/// frames. Alternating frames see the same load and nearly the same content, and one odd frame
/// on either side does not decide; keeping a slower setting by chance costs frames until the
/// next probe, so keeping asks for more than the median. A probe that loses is not repeated
/// for a while, twice as long after each loss (from kMinHoldFrames up to kMaxHoldFrames), so a
/// steady load costs at most a few slower frames in kMaxHoldFrames. When the current setting's
/// frames (the mean of the middle half of the last kRecentFrames) stay kShift slower or faster
/// than they were at the last decision for kShiftFrames frames (the load changed, or the
/// scene), the waits are cleared and every neighbour is probed again at once. Frames are
/// compared by wall time, the whole frame's work (a burst of WorkerPool).
///
/// Pure bookkeeping: no clock, no allocation; one thread (the pool's caller).

#include <array>

namespace omnipose::runtime {

/// How one frame runs on the pool.
struct PoolSetting {
  int workers = 1;    ///< workers taking part, the caller included, >= 1
  bool spin = true;   ///< between jobs the workers spin (yielding the core) rather than sleep
  bool operator==(const PoolSetting&) const = default;
};

class WorkerCountTuner {
 public:
  /// A probe's setting is kept when the median of its frames is this much faster (and so are
  /// all but one of its frames against their neighbours).
  static constexpr double kGain = 0.05;
  /// Frames of each setting in one probe (the probe is twice as many frames, alternating).
  static constexpr int kProbeFrames = 3;
  /// Frames between a lost probe and the next in the same direction: the first, and the most.
  static constexpr int kMinHoldFrames = 30;
  static constexpr int kMaxHoldFrames = 480;
  /// Relative change of the current setting's recent frame time that clears the waits, and for
  /// how many frames in a row it must hold.
  static constexpr double kShift = 0.25;
  static constexpr int kShiftFrames = 3;
  /// Frames of the current setting whose middle half's mean is its recent frame time (also the
  /// frames it runs before it is probed from).
  static constexpr int kRecentFrames = 8;

  /// `workers` >= 1: the pool's size, the caller included. All take part at first, spinning.
  explicit WorkerCountTuner(int workers);

  /// The setting of the next frame.
  PoolSetting active() const { return active_; }
  /// The setting the frames run on outside probes.
  PoolSetting current() const { return current_; }

  /// After a frame run with active(): its wall time in seconds (frames without a positive,
  /// finite time are ignored). Returns active() for the next frame.
  PoolSetting frameEnded(double seconds);

 private:
  struct Direction {
    int hold = 0;                  ///< frames before the next probe this way is allowed
    /// The hold after the next lost probe this way: kMinHoldFrames after a kept probe, doubled
    /// by each lost one up to kMaxHoldFrames.
    int backoff = kMinHoldFrames;
  };
  enum Way { kFewer, kMore, kOtherWait, kWays };

  /// The neighbour of the current setting `way`, or nothing (workers 0) where there is none.
  PoolSetting neighbour(Way way) const;
  /// Records one frame of the probe; judges it after its last frame.
  void probeFrame(double seconds);
  /// The probe is over: keep its setting when it was faster, else go back and wait.
  void judgeProbe();

  int workers_;
  PoolSetting current_;
  PoolSetting active_;
  int probing_ = -1;     ///< the Way being probed; -1 = no probe running
  PoolSetting candidate_;
  int probe_frame_ = 0;  ///< frames of the running probe so far
  std::array<double, kProbeFrames> candidate_times_{}, current_times_{};
  std::array<double, kRecentFrames> recent_{};  ///< the current setting's last frames (a ring)
  int frames_ = 0;          ///< frames run on the current setting outside probes
  double reference_ = 0.0;  ///< the recent frame time at the last decision; 0 = not yet set
  int shifted_frames_ = 0;  ///< frames in a row whose recent frame time left kShift of it
  std::array<Direction, kWays> ways_{};
};

}  // namespace omnipose::runtime
