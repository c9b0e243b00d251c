#pragma once
/// \file capture_loop.hpp
/// The capture thread's loop: pull frames from the FrameSource into the mailbox's write
/// slot and post them; turn every source failure into status and a gap, never into a crash.
///
/// Reconnection has one owner, this loop, for every source (file, V4L2, libcamera): a
/// source that fails reports it from next() and releases what it held; the loop closes it
/// and re-opens it with a bounded back-off. The sources have no retry logic of their own.
///
///  - kTimeout: nothing yet, call again (the loop wakes at least every `poll`).
///  - every frame the source delivers, reports bad, or is known to have dropped counts as
///    received (counters.hpp: received = processed + skipped + bad + lost upstream);
///  - kBadFrame: counted (frames_bad), reported with the source's text (which names the
///    file or frame), gap marked; streaming goes on.
///  - kDisconnected or any other error: counted once (source_failures: one per outage, not
///    per attempt), reported, source state SOURCE_RECONNECTING, the source is closed and
///    re-opened with exponential back-off (Backoff: `reconnect_initial`, doubling, capped at
///    `reconnect_max`; every failed attempt is reported, stop is honoured while waiting); a
///    re-opened source must deliver the same frame size; gap marked; state back to
///    streaming. No frame is counted for the outage: frames a camera did not capture while
///    it was away are not received, and the sequence number expected next is forgotten.
///  - kEndOfStream: the source state becomes ended and the mailbox is closed, so the
///    processor drains the last frame and the daemon can exit.
///  - A restart of a file source's index (loop: the recording jumps back) is a gap as well.
///  - A jump in the source's sequence number (frames the source or driver dropped because
///    nobody read them in time) is counted (frames_lost_upstream) but is not a gap: like a
///    stale frame skipped by the mailbox, the next frame is registered directly against the
///    last processed one, and a motion too large for that makes the fit report lost.
///    Frames passed over before the first one after (re-)opening count too when the source
///    knows where its numbering starts (FrameSource::sequenceOrigin()).
///  - A frame the source resynchronised its pacing on (a forward jump in recorded
///    timestamps beyond its bound) is reported once and processed.
///
/// Allocation: none in this loop (the source's own work aside).

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <opencv2/core.hpp>

#include "daemon/frame_mailbox.hpp"
#include "daemon/status_board.hpp"
#include "omnipose/frame_source.hpp"

namespace omnipose::daemon {

/// Exponential back-off of the re-open attempts: next() returns initial, 2 initial,
/// 4 initial, ... capped at max; reset() starts over. An initial below 1 ms is taken as 1 ms,
/// a max below initial as initial, so the delays are always in [1 ms, max].
class Backoff {
 public:
  Backoff(std::chrono::milliseconds initial, std::chrono::milliseconds max)
      : initial_(std::max(initial, std::chrono::milliseconds(1))),
        max_(std::max(max, initial_)),
        current_(initial_) {}
  /// The delay before the next attempt; doubles the one after it (up to the cap).
  std::chrono::milliseconds next() {
    const auto d = current_;
    current_ = current_ > max_ / 2 ? max_ : current_ * 2;
    return d;
  }
  void reset() { current_ = initial_; }

 private:
  std::chrono::milliseconds initial_;
  std::chrono::milliseconds max_;
  std::chrono::milliseconds current_;
};

class CaptureLoop {
 public:
  struct Options {
    std::chrono::milliseconds poll{100};               ///< longest wait inside next()
    std::chrono::milliseconds reconnect_initial{100};  ///< first re-open delay (>= 1 ms)
    std::chrono::milliseconds reconnect_max{2000};     ///< back-off cap (>= the first)
  };

  /// All borrowed; `source` must be open already (start-up opens it).
  CaptureLoop(FrameSource& source, FrameMailbox& mailbox, StatusBoard& board, Options options);

  /// Runs until stop (mailbox.requestStop()) or the end of the stream; closes the source.
  void run();

 private:
  /// What the loop knows of the frames since the source was (re-)opened.
  struct Timeline {
    bool have_last = false;
    int last_index = -1;
    std::int64_t last_capture_us = 0;
    double last_source_timestamp = 0.0;
    /// The sequence number the next frame should carry: a larger one means frames were
    /// lost upstream (unknown after a camera's re-open until its first frame arrives).
    std::optional<std::uint64_t> expected_sequence;
  };

  /// Waits `delay` unless stop is requested first; true when stop was requested.
  bool sleepUnlessStopped(std::chrono::milliseconds delay);
  bool reopen();
  /// A frame the source delivered: counts the frames lost upstream before it, marks a gap
  /// where its index or time goes backwards, and posts it.
  void accept(const FrameInfo& frame);
  /// A failed next(): counts and reports it; closes the source on a fault (open_ false: the
  /// loop re-opens it). False at the end of the stream (the loop returns).
  bool handleFailure(const Error& error);

  FrameSource& source_;
  FrameMailbox& mailbox_;
  StatusBoard& board_;
  Options options_;
  cv::Size frame_size_;
  std::string description_;  ///< source_.describe() at start-up (logging must not allocate)
  bool open_ = true;
  Timeline timeline_;
};

}  // namespace omnipose::daemon
