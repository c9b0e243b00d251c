#include "daemon/capture_loop.hpp"

#include <algorithm>
#include <optional>
#include <thread>

#include "daemon/wall_clock.hpp"

namespace omnipose::daemon {

CaptureLoop::CaptureLoop(FrameSource& source, FrameMailbox& mailbox, StatusBoard& board,
                         Options options)
    : source_(source),
      mailbox_(mailbox),
      board_(board),
      options_(options),
      frame_size_(source.frameSize()),
      description_(source.describe()) {}

bool CaptureLoop::sleepUnlessStopped(std::chrono::milliseconds delay) {
  const auto deadline = SteadyClock::now() + delay;
  while (!mailbox_.stopRequested()) {
    const auto now = SteadyClock::now();
    if (now >= deadline) return false;
    board_.beatCapture();
    std::this_thread::sleep_for(std::min<SteadyClock::duration>(deadline - now, options_.poll));
  }
  return true;
}

bool CaptureLoop::reopen() {
  if (auto opened = source_.open(); !opened) {
    board_.reportError(opened.error());
    return false;
  }
  if (source_.frameSize() != frame_size_) {
    board_.reportError("%s: re-opened with %dx%d frames, expected %dx%d", description_.c_str(), source_.frameSize().width,
                       source_.frameSize().height, frame_size_.width, frame_size_.height);
    source_.close();
    return false;
  }
  return true;
}

void CaptureLoop::accept(const FrameInfo& got) {
  Timeline& t = timeline_;
  if (t.expected_sequence && got.sequence > *t.expected_sequence) {
    const auto lost = static_cast<std::int64_t>(got.sequence - *t.expected_sequence);
    board_.frames_lost_upstream += lost;
    board_.frames_received += lost;
  }
  t.expected_sequence = got.sequence + 1;
  if (got.resynchronised) {
    board_.reportError("%s: frame %d: timestamp %.6f s is more than the pacing bound after "
                       "the previous frame's: pacing resynchronised, not waited out",
                       description_.c_str(), got.index, got.source_timestamp);
  }
  if (t.have_last && got.index >= 0 && got.index <= t.last_index) mailbox_.markGap();
  // Time must move forward: a frame stamped at or before its predecessor (a camera
  // clock step, a broken recording) cannot be linked to it by time. It is processed
  // after a gap: the odometry finds it again by the whole-ring search (a new segment
  // only when that fails); the fault is reported.
  else if (t.have_last && got.capture_time_us < t.last_capture_us) {
    board_.reportError("%s: frame %llu: capture time %lld us is before the previous "
                       "frame's %lld us (time went backwards): bridged as after a gap",
                       description_.c_str(), static_cast<unsigned long long>(got.sequence),
                       static_cast<long long>(got.capture_time_us),
                       static_cast<long long>(t.last_capture_us));
    mailbox_.markGap();
  } else if (t.have_last && got.index > t.last_index &&
             got.source_timestamp < t.last_source_timestamp) {
    board_.reportError("%s: frame %d: timestamp %.6f s is before the previous frame's "
                       "%.6f s (time went backwards): bridged as after a gap",
                       description_.c_str(), got.index, got.source_timestamp,
                       t.last_source_timestamp);
    mailbox_.markGap();
  }
  t.have_last = true;
  t.last_index = got.index;
  t.last_capture_us = got.capture_time_us;
  t.last_source_timestamp = got.source_timestamp;
  ++board_.frames_received;
  mailbox_.post(got);
}

bool CaptureLoop::handleFailure(const Error& error) {
  switch (error.code()) {
    case ErrorCode::kTimeout:
      break;
    case ErrorCode::kBadFrame:
      ++board_.frames_received;
      ++board_.frames_bad;
      // The bad frame used a sequence number: not lost.
      if (timeline_.expected_sequence) ++*timeline_.expected_sequence;
      board_.reportError(error);
      mailbox_.markGap();
      break;
    case ErrorCode::kEndOfStream:
      board_.setSourceState(SourceState::kEnded);
      board_.logInfo("end of stream: %s", error.c_str());
      return false;
    default:  // kDisconnected, kIoError, ...: close, re-open with back-off
      ++board_.source_failures;
      board_.reportError(error);
      board_.setSourceState(SourceState::kReconnecting);
      source_.close();
      open_ = false;
      timeline_.have_last = false;
      timeline_.expected_sequence.reset();
      mailbox_.markGap();
      break;
  }
  return true;
}

void CaptureLoop::run() {
  board_.setSourceState(SourceState::kStreaming);
  open_ = true;
  timeline_ = Timeline{};
  timeline_.expected_sequence = source_.sequenceOrigin();
  Backoff backoff(options_.reconnect_initial, options_.reconnect_max);

  while (!mailbox_.stopRequested()) {
    board_.beatCapture();
    if (!open_) {
      // Re-open with exponential back-off.
      if (sleepUnlessStopped(backoff.next())) break;
      if (!reopen()) continue;
      open_ = true;
      timeline_.expected_sequence = source_.sequenceOrigin();
      backoff.reset();
      board_.setSourceState(SourceState::kStreaming);
      board_.logInfo("source re-opened: %s", description_.c_str());
      mailbox_.markGap();
      continue;
    }
    // Lossless replay: read the next frame only when the processor took the last one.
    if (!mailbox_.waitUntilTaken(options_.poll)) continue;

    Expected<FrameInfo> got = source_.next(mailbox_.writeBuffer(), options_.poll);
    if (got) {
      accept(*got);
    } else if (!handleFailure(got.error())) {
      source_.close();
      mailbox_.close();
      board_.markCaptureFinished();
      return;
    }
  }
  source_.close();
  board_.setSourceState(SourceState::kStopped);
  mailbox_.close();
  board_.markCaptureFinished();
}

}  // namespace omnipose::daemon
