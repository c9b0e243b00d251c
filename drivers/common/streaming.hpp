#pragma once
/// \file streaming.hpp
/// The streaming policy both camera drivers (V4L2, libcamera) share, free of any device:
///
///   planDrain()        which of the frames completed since the last look is delivered
///                      (the newest good one) and when even that one is stale ("ran dry")
///   SequenceTracker    the driver's 32-bit frame counter as a 64-bit sequence that goes on
///                      across wraps and stream restarts; frames the driver dropped
///
/// The drivers keep what is theirs: the device calls, requeueing, their counters and error
/// messages. Reconnecting is not theirs: a driver that loses its device releases it and
/// reports kDisconnected; the owner of the source closes and re-opens it (the daemon's
/// capture loop, src/daemon/capture_loop.hpp, with its back-off). Everything here is
/// allocation-free and not thread-safe (one capture thread).
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
/// Appends the problems of the clock timing, named by their option fields: clock_resync
/// >= 1 ms, clock_samples (bracketed clock reads per offset measurement) in
/// [1, kMaxClockSamples].
void appendClockProblems(std::vector<std::string>& problems,
                         std::chrono::milliseconds clock_resync, int clock_samples);

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
/// dropped. The counter restarts with every stream (a close() and open()).
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
