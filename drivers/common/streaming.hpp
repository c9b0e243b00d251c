#pragma once
/// \file streaming.hpp
/// The streaming policy both camera drivers (V4L2, libcamera) share, free of any device:
///
///   ReconnectSchedule  when to try reopening a device that went away (exponential
///                      back-off, a caller's deadline honoured)
///   planDrain()        which of the frames completed since the last look is delivered
///                      (the newest good one) and when even that one is stale ("ran dry")
///   SequenceTracker    the driver's 32-bit frame counter as a 64-bit sequence that goes on
///                      across wraps and stream restarts; frames the driver dropped
///
/// The drivers keep what is theirs: the device calls, requeueing, their counters and error
/// messages. Everything here is allocation-free and not thread-safe (one capture thread).
///
/// Units: times are nanoseconds on the driver's monotonic clock unless a name says _us
/// (microseconds) or _ms (milliseconds); delays are milliseconds.

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace omnipose::drivers {

// ---------------------------------------------------------------------------------------
// Options every camera driver shares
// ---------------------------------------------------------------------------------------

/// Appends the problems of the stream request, named by their daemon.yaml keys:
/// source.width and source.height in [1, 16384] pixels, source.fps in (0, 1000] (NaN refused).
void appendStreamRequestProblems(std::vector<std::string>& problems, int width, int height,
                                 double fps);
/// Appends the problems of the reconnect and clock timing, named by their option fields:
/// reconnect_initial and clock_resync >= 1 ms, reconnect_max >= reconnect_initial,
/// clock_samples (bracketed clock reads per offset measurement) in [1, kMaxClockSamples].
void appendTimingProblems(std::vector<std::string>& problems,
                          std::chrono::milliseconds reconnect_initial,
                          std::chrono::milliseconds reconnect_max,
                          std::chrono::milliseconds clock_resync, int clock_samples);

// ---------------------------------------------------------------------------------------
// Reconnect back-off
// ---------------------------------------------------------------------------------------

/// Exponential back-off for reconnect attempts: next() returns initial, 2 initial,
/// 4 initial, ... capped at max; reset() starts over. Milliseconds. An initial below 1 is
/// taken as 1, a max below initial as initial.
class Backoff {
 public:
  Backoff(std::int64_t initial_ms, std::int64_t max_ms)
      : initial_ms_(initial_ms < 1 ? 1 : initial_ms),
        max_ms_(max_ms < initial_ms_ ? initial_ms_ : max_ms),
        current_ms_(initial_ms_) {}
  /// The delay before the next attempt, then doubles the one after it.
  std::int64_t next() {
    const std::int64_t d = current_ms_;
    current_ms_ = current_ms_ > max_ms_ / 2 ? max_ms_ : current_ms_ * 2;
    return d;
  }
  void reset() { current_ms_ = initial_ms_; }

 private:
  std::int64_t initial_ms_;
  std::int64_t max_ms_;
  std::int64_t current_ms_;
};

/// When to reopen a device that went away. The schedule after a loss at time T with
/// initial 100 ms, max 800 ms: attempts at T+100; on failure +200, +400, +800, +800, ...
/// after each failed attempt; reconnected() (or the next lost()) starts over.
///
/// A driver's recover(deadline):
///   for (;;) {
///     auto s = schedule.step(now(), deadline);
///     if (s.action == Action::kAttempt) break;
///     sleep(s.sleep_ns);
///     if (s.action == Action::kGiveBack) return kDisconnected;   // caller's time is up
///   }
///   reopen() ? schedule.reconnected() : schedule.attemptFailed(now());
class ReconnectSchedule {
 public:
  enum class Action {
    kAttempt,   ///< the attempt is due: reopen now
    kWait,      ///< sleep sleep_ns (until the attempt is due), then ask again
    kGiveBack,  ///< the attempt is due after the caller's deadline: sleep sleep_ns (to the
                ///< deadline), then return to the caller still disconnected
  };
  struct Step {
    Action action = Action::kAttempt;
    std::int64_t sleep_ns = 0;  ///< >= 0
  };

  ReconnectSchedule(std::chrono::milliseconds initial, std::chrono::milliseconds max)
      : backoff_(initial.count(), max.count()) {}

  /// The device went away at `now_ns`: the back-off starts over and the first attempt is
  /// due one initial delay later.
  void lost(std::int64_t now_ns);
  /// What to do at `now_ns` for a caller that waits at most until `deadline_ns`.
  Step step(std::int64_t now_ns, std::int64_t deadline_ns) const;
  /// The attempt made at `now_ns` failed: the next is due after the next back-off delay,
  /// which is returned (milliseconds).
  std::int64_t attemptFailed(std::int64_t now_ns);
  /// The device is back: the next loss starts the back-off over.
  void reconnected() { backoff_.reset(); }
  /// When the next attempt is due, nanoseconds.
  std::int64_t retryAtNs() const { return retry_at_ns_; }

 private:
  Backoff backoff_;
  std::int64_t retry_at_ns_ = 0;
};

// ---------------------------------------------------------------------------------------
// Drain to the newest frame
// ---------------------------------------------------------------------------------------

/// What to do with the frames a driver took from the device in one look, oldest first.
struct DrainPlan {
  /// Index (oldest first) of the frame to deliver, -1 for none: either ran_dry, or no frame
  /// is good (every one flagged by the driver: a bad-frame error). Every other frame is
  /// given back to the device (counted as stale when good, as an error when not).
  int deliver = -1;
  /// Every buffer had completed: the device had nothing to capture into, newer frames were
  /// lost and even the newest one held is old. All go back; wait for a fresh frame.
  bool ran_dry = false;
};

/// `completed`: frames taken in this look; `queued_before`: buffers that were queued with
/// the device before it; `total`: buffers the source owns; `good(i)`: frame i (0 = oldest)
/// completed without an error. Ran dry = drop_stale && completed > 1 && completed ==
/// queued_before == total (with a single buffer every frame would count as stale, so one
/// is never dropped as such). Otherwise the newest good frame is delivered.
template <typename IsGood>
DrainPlan planDrain(std::size_t completed, std::size_t queued_before, std::size_t total,
                    bool drop_stale, IsGood&& good) {
  DrainPlan plan;
  if (drop_stale && completed > 1 && completed == queued_before && completed == total) {
    plan.ran_dry = true;
    return plan;
  }
  for (std::size_t i = completed; i-- > 0;)
    if (good(i)) {
      plan.deliver = static_cast<int>(i);
      break;
    }
  return plan;
}

// ---------------------------------------------------------------------------------------
// Sequence numbers
// ---------------------------------------------------------------------------------------

/// The driver's 32-bit frame counter (V4L2 v4l2_buffer::sequence, libcamera
/// FrameMetadata::sequence) as FrameInfo's 64-bit sequence, and the frames the driver
/// dropped. The counter restarts with every stream (a reconnect, a close() and open()).
class SequenceTracker {
 public:
  /// A stream (re)started: the driver's counter starts over. The next completed() counts
  /// no loss; the next delivered() continues from the last delivered sequence with the gap
  /// the elapsed time implies.
  void restart() {
    have_completed_ = false;
    restarted_ = true;
  }

  /// Every buffer the driver completed, in completion order: the frames it dropped between
  /// the previous one and this (a sequence gap; the difference is taken modulo 2^32, so a
  /// wrap is no gap). 0 for the first after restart() and for a repeated number.
  std::uint32_t completed(std::uint32_t driver_sequence);

  /// The frame about to be delivered, captured at `capture_time_us` (wall clock), from a
  /// stream running at `fps` (0 = unknown). Returns its 64-bit sequence:
  ///   the first frame ever:        driver_sequence
  ///   within a stream:             previous + (driver_sequence - previous driver's) mod 2^32
  ///   first after restart():       previous + max(1, round((capture_time_us - previous
  ///                                capture) * 1e-6 * fps)); + 1 when fps is 0 or the
  ///                                capture time did not advance
  std::uint64_t delivered(std::uint32_t driver_sequence, std::int64_t capture_time_us,
                          double fps);

  /// Whether any frame was delivered.
  bool started() const { return have_sequence_; }

 private:
  bool have_completed_ = false;
  std::uint32_t last_completed_ = 0;

  bool have_sequence_ = false;
  bool restarted_ = false;
  std::uint32_t last_delivered_driver_ = 0;
  std::uint64_t sequence_ = 0;
  std::int64_t last_capture_us_ = 0;
};

}  // namespace omnipose::drivers
