#pragma once
/// \file status_board.hpp
/// Counters and state shared by the capture and processing threads and read by the status
/// publisher and the watchdog: lock-free counters, the source state, the last error text
/// (a fixed buffer under a mutex) and per-thread heartbeats. Allocation-free after
/// construction; every member function is thread-safe.
///
/// Faults are also logged (one line each, at most one line per `kLogInterval`; the count of
/// suppressed lines is reported with the next one).

#include <array>
#include <atomic>
#include <chrono>
#include <cstdint>
#include <cstdio>
#include <mutex>
#include <string_view>

#include "omnipose/error.hpp"

namespace omnipose::daemon {

/// What the frame source is doing (the values of status_t.SOURCE_*).
enum class SourceState : std::int8_t {
  kStarting = 0,
  kStreaming = 1,
  kReconnecting = 2,
  kEnded = 3,
  kStopped = 4,
};
const char* toString(SourceState state);

/// A snapshot of the counters (totals since start-up). Every frame is counted once: once
/// both threads have finished, frames_received = frames_processed + frames_skipped +
/// frames_bad + frames_lost_upstream.
struct DaemonStats {
  std::int64_t frames_received = 0;   ///< frames delivered by the source or known dropped
  std::int64_t frames_processed = 0;  ///< frames the pipeline ran on (= poses published)
  std::int64_t frames_skipped = 0;    ///< stale frames overwritten or left at the stop
  std::int64_t frames_bad = 0;        ///< corrupt / wrong-size / pipeline-rejected frames
  std::int64_t frames_lost_upstream = 0;  ///< sequence numbers the source skipped
  std::int64_t poses_lost = 0;        ///< poses published with status lost
  std::int64_t source_failures = 0;   ///< source failures that needed a re-open
  std::int64_t publish_failures = 0;  ///< encode or LCM publish errors
  int segment = -1;                   ///< current chain segment (-1 before the first frame)
  SourceState source_state = SourceState::kStarting;
};

class StatusBoard {
 public:
  static constexpr std::chrono::milliseconds kLogInterval{200};

  /// `log`: where faults are written (borrowed; nullptr = nowhere).
  explicit StatusBoard(std::FILE* log);

  std::atomic<std::int64_t> frames_received{0};
  std::atomic<std::int64_t> frames_processed{0};
  std::atomic<std::int64_t> frames_bad{0};
  std::atomic<std::int64_t> frames_lost_upstream{0};
  std::atomic<std::int64_t> poses_lost{0};
  std::atomic<std::int64_t> source_failures{0};
  std::atomic<std::int64_t> publish_failures{0};
  std::atomic<int> segment{-1};

  void setSourceState(SourceState state) { source_state_.store(state); }
  SourceState sourceState() const { return source_state_.load(); }

  /// Records (and logs) a fault; the text should name the file, frame or device.
  void reportError(const Error& error);
  /// printf-style variant.
  [[gnu::format(printf, 2, 3)]] void reportError(const char* fmt, ...);
  /// Logs an informational line (not an error), not rate-limited.
  [[gnu::format(printf, 2, 3)]] void logInfo(const char* fmt, ...);
  /// Copies the last error text (NUL-terminated, truncated to `capacity`) and returns its
  /// wall-clock time in microseconds (0 = no error yet).
  std::int64_t lastError(char* text, std::size_t capacity) const;

  /// Heartbeats for the watchdog: each loop iteration of a thread beats.
  void beatCapture() { capture_beat_ns_.store(nowNs()); }
  void beatProcessor() { processor_beat_ns_.store(nowNs()); }
  /// Whether both threads beat within `max_silence` (a finished thread counts as alive
  /// once marked with markFinished...()).
  bool alive(std::chrono::nanoseconds max_silence) const;
  void markCaptureFinished() { capture_finished_.store(true); }
  void markProcessorFinished() { processor_finished_.store(true); }

 private:
  static std::int64_t nowNs();
  void record(const char* text);

  std::FILE* log_;
  std::atomic<SourceState> source_state_{SourceState::kStarting};
  mutable std::mutex error_mutex_;
  std::array<char, Error::kCapacity> last_error_{};
  std::int64_t last_error_utime_ = 0;
  std::int64_t last_log_ns_ = 0;
  std::int64_t suppressed_ = 0;
  std::atomic<std::int64_t> capture_beat_ns_{0};
  std::atomic<std::int64_t> processor_beat_ns_{0};
  std::atomic<bool> capture_finished_{false};
  std::atomic<bool> processor_finished_{false};
};

}  // namespace omnipose::daemon
