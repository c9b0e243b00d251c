#pragma once
/// \file frame_mailbox.hpp
/// The hand-off between the capture thread and the processing thread: a latest-frame
/// mailbox over preallocated slots (triple buffering). The capture thread fills the write
/// slot (never the newest unread one nor the one being processed) and posts it; the
/// processor takes the newest posted frame. A posted frame that is overwritten by a newer
/// one before the processor took it is dropped and counted as skipped (stale): a robot
/// wants fresh pose, not a backlog (DESIGN.md section 5). At a stop, the posted frame that
/// was never taken, and any frame posted after the stop, count as skipped too: at the end,
/// posted = processed + skipped + rejected by the pipeline.
///
/// Gaps: markGap() (bad frame, source reconnect) flags the next posted frame; the flag
/// survives when that frame is itself overwritten, so the processor always learns that the
/// link to its previous frame is broken.
///
/// Backpressure (lossless replay): with `lossless`, waitUntilTaken() lets the capture
/// thread wait until the processor has taken the last frame before it reads the next one,
/// so nothing is skipped.
///
/// Allocation: only the constructor allocates. Threading: one capture thread (writer side),
/// one processing thread (reader side); requestStop()/close() and the counters from any.

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <opencv2/core.hpp>
#include <vector>

#include "omnipose/frame_source.hpp"

namespace omnipose::daemon {

/// What comes with a frame taken from the mailbox.
struct MailboxFrame {
  const cv::Mat* image = nullptr;  ///< valid until release()
  FrameInfo info;
  bool gap_before = false;         ///< the link to the previously taken frame is broken
  std::int64_t skipped_before = 0; ///< stale frames dropped since the previously taken one
};

class FrameMailbox {
 public:
  /// Allocates `slots` (>= 3) CV_8UC1 buffers of `size`. Skipped frames are counted in
  /// `*skipped_counter` when given (the daemon passes StatusBoard::frames_skipped_stale;
  /// borrowed, must outlive the mailbox), else in a counter of the mailbox's own.
  FrameMailbox(cv::Size size, bool lossless, int slots = 3,
               std::atomic<std::int64_t>* skipped_counter = nullptr);
  FrameMailbox(const FrameMailbox&) = delete;
  FrameMailbox& operator=(const FrameMailbox&) = delete;

  // --- capture thread ---------------------------------------------------------------
  /// The buffer to fill next (frame size, CV_8UC1; fill it in place, do not reallocate).
  cv::Mat& writeBuffer();
  /// Posts the write buffer as the newest frame; returns true when an unread frame was
  /// dropped to make room (counted as skipped).
  bool post(const FrameInfo& info);
  /// The next posted frame follows a gap.
  void markGap();
  /// Lossless mode: waits until the last posted frame was taken (or stop/timeout); true
  /// when there is room. Without lossless: always true at once.
  bool waitUntilTaken(std::chrono::milliseconds timeout);
  /// No more frames will come (end of stream): the processor drains what is there, then
  /// take() reports kClosed.
  void close();

  // --- processing thread ------------------------------------------------------------
  enum class TakeResult { kFrame, kTimeout, kClosed };
  /// Waits until `deadline` for a frame. kClosed after requestStop(), or after close()
  /// once the last frame was taken.
  TakeResult take(std::chrono::steady_clock::time_point deadline, MailboxFrame& out);
  /// Returns the taken slot (call before the next take()).
  void release();

  // --- any thread -------------------------------------------------------------------
  /// Stop now: wakes both sides; take() returns kClosed, waitUntilTaken() false.
  void requestStop();
  bool stopRequested() const;
  std::int64_t posted() const;
  /// Frames skipped so far (the value of the skipped counter).
  std::int64_t skipped() const;

 private:
  struct Slot {
    cv::Mat image;
    FrameInfo info;
    bool gap_before = false;
    std::int64_t skipped_before = 0;
  };
  int freeSlotLocked() const;

  std::vector<Slot> slots_;
  const bool lossless_;
  mutable std::mutex mutex_;
  std::condition_variable frame_ready_;  ///< processor waits here
  std::condition_variable frame_taken_;  ///< capture waits here (lossless)
  int writing_ = 0;    ///< slot the capture thread fills
  int ready_ = -1;     ///< newest posted, not yet taken
  int reading_ = -1;   ///< taken by the processor
  bool pending_gap_ = false;
  std::int64_t pending_skipped_ = 0;
  bool closed_ = false;
  bool stop_ = false;
  std::int64_t posted_ = 0;
  std::atomic<std::int64_t> own_skipped_{0};
  std::atomic<std::int64_t>& skipped_;  ///< own_skipped_ or the caller's counter
};

}  // namespace omnipose::daemon
