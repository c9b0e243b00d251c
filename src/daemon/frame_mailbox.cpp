#include "daemon/frame_mailbox.hpp"

#include <stdexcept>

namespace omnipose::daemon {

FrameMailbox::FrameMailbox(cv::Size size, bool lossless, int slots,
                           std::atomic<std::int64_t>* skipped_counter)
    : lossless_(lossless), skipped_(skipped_counter != nullptr ? *skipped_counter : own_skipped_) {
  if (slots < 3) throw std::invalid_argument("FrameMailbox: needs at least 3 slots");
  if (size.width <= 0 || size.height <= 0) throw std::invalid_argument("FrameMailbox: empty frame size");
  slots_.resize(static_cast<std::size_t>(slots));
  for (auto& s : slots_) s.image = cv::Mat(size, CV_8UC1, cv::Scalar(0));
}

int FrameMailbox::freeSlotLocked() const {
  for (int i = 0; i < static_cast<int>(slots_.size()); ++i) {
    if (i != ready_ && i != reading_) return i;
  }
  return -1;  // impossible with >= 3 slots
}

cv::Mat& FrameMailbox::writeBuffer() {
  // writing_ is only changed by post() on this same (capture) thread.
  return slots_[static_cast<std::size_t>(writing_)].image;
}

bool FrameMailbox::post(const FrameInfo& info) {
  bool dropped = false;
  {
    std::lock_guard lock(mutex_);
    ++posted_;
    if (stop_) {  // read while the stop came: it will never be processed
      ++skipped_;
      return true;
    }
    Slot& slot = slots_[static_cast<std::size_t>(writing_)];
    slot.info = info;
    if (ready_ >= 0) {  // the newest frame was never taken: it is stale now
      const Slot& stale = slots_[static_cast<std::size_t>(ready_)];
      pending_gap_ = pending_gap_ || stale.gap_before;
      pending_skipped_ += stale.skipped_before + 1;
      ++skipped_;
      dropped = true;
    }
    slot.gap_before = pending_gap_;
    slot.skipped_before = pending_skipped_;
    pending_gap_ = false;
    pending_skipped_ = 0;
    ready_ = writing_;
    writing_ = freeSlotLocked();
  }
  frame_ready_.notify_one();
  return dropped;
}

void FrameMailbox::markGap() {
  std::lock_guard lock(mutex_);
  pending_gap_ = true;
}

bool FrameMailbox::waitUntilTaken(std::chrono::milliseconds timeout) {
  if (!lossless_) return !stopRequested();
  std::unique_lock lock(mutex_);
  frame_taken_.wait_for(lock, timeout, [&] { return stop_ || ready_ < 0; });
  return !stop_ && ready_ < 0;
}

void FrameMailbox::close() {
  {
    std::lock_guard lock(mutex_);
    closed_ = true;
  }
  frame_ready_.notify_all();
}

FrameMailbox::TakeResult FrameMailbox::take(std::chrono::steady_clock::time_point deadline,
                                            MailboxFrame& out) {
  std::unique_lock lock(mutex_);
  frame_ready_.wait_until(lock, deadline, [&] { return stop_ || closed_ || ready_ >= 0; });
  if (stop_) return TakeResult::kClosed;
  if (ready_ < 0) return closed_ ? TakeResult::kClosed : TakeResult::kTimeout;
  reading_ = ready_;
  ready_ = -1;
  const Slot& slot = slots_[static_cast<std::size_t>(reading_)];
  out.image = &slot.image;
  out.info = slot.info;
  out.gap_before = slot.gap_before;
  out.skipped_before = slot.skipped_before;
  lock.unlock();
  frame_taken_.notify_all();
  return TakeResult::kFrame;
}

void FrameMailbox::release() {
  std::lock_guard lock(mutex_);
  reading_ = -1;
}

void FrameMailbox::requestStop() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
    // A posted frame the processor never took is dropped: counted as skipped, so that at
    // the end every received frame is processed, skipped or bad.
    if (ready_ >= 0) {
      ++skipped_;
      ready_ = -1;
    }
  }
  frame_ready_.notify_all();
  frame_taken_.notify_all();
}

bool FrameMailbox::stopRequested() const {
  std::lock_guard lock(mutex_);
  return stop_;
}

std::int64_t FrameMailbox::posted() const {
  std::lock_guard lock(mutex_);
  return posted_;
}

std::int64_t FrameMailbox::skipped() const { return skipped_.load(); }

}  // namespace omnipose::daemon
