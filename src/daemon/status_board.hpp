#pragma once
/// \file status_board.hpp
/// Counters and state shared by the capture and processing threads and read by the status
/// publisher and the watchdog: lock-free counters (the table of counters.hpp), the source
/// state, the last error text (a fixed buffer under a mutex) and per-thread heartbeats.
/// Allocation-free after construction; every member function is thread-safe.
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

#include "daemon/counters.hpp"
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

/// A snapshot of the board: the counters of counters.hpp (totals since start-up, each
/// field named as in status_t) and the state. The frame-counting invariant
/// (counters.hpp) holds for a snapshot taken after both threads have finished.
struct DaemonStats {
#define OMNIPOSE_STATS_FIELD(name, label, description) std::int64_t name = 0;
  OMNIPOSE_DAEMON_COUNTERS(OMNIPOSE_STATS_FIELD)
#undef OMNIPOSE_STATS_FIELD
  int segment = -1;                   ///< current chain segment (-1 before the first frame)
  int places = 0;                     ///< places in the odometry's memory
  SourceState source_state = SourceState::kStarting;
  /// Messages (pose, status, diagnostics) published without an error: with
  /// publish_failures, tells a run whose every message failed (not part of status_t).
  std::int64_t messages_published = 0;
  /// The map written to loop_closure.map_file, and the writes that failed (map_keeper.hpp).
  std::int64_t maps_saved = 0;
  std::int64_t map_save_failures = 0;
};

/// Fills the counters, segment, places, map saves and source state of a status message
/// (status_t) from a snapshot. Allocation-free.
template <typename Status>
void fillStatus(const DaemonStats& stats, Status& status) {
  copyCounters(stats, status);
  status.segment = stats.segment;
  status.places = stats.places;
  status.maps_saved = stats.maps_saved;
  status.map_save_failures = stats.map_save_failures;
  status.source_state = static_cast<std::int8_t>(stats.source_state);
}

class StatusBoard {
 public:
  static constexpr std::chrono::milliseconds kLogInterval{200};

  /// `log`: where faults are written (borrowed; nullptr = nowhere).
  explicit StatusBoard(std::FILE* log);

  /// The counters of counters.hpp, one lock-free atomic each (incremented by the thread
  /// that sees the event; the mailbox counts frames_skipped_stale).
#define OMNIPOSE_BOARD_COUNTER(name, label, description) std::atomic<std::int64_t> name{0};
  OMNIPOSE_DAEMON_COUNTERS(OMNIPOSE_BOARD_COUNTER)
#undef OMNIPOSE_BOARD_COUNTER
  std::atomic<int> segment{-1};
  std::atomic<int> places{0};
  std::atomic<std::int64_t> maps_saved{0};         ///< DaemonStats::maps_saved
  std::atomic<std::int64_t> map_save_failures{0};  ///< DaemonStats::map_save_failures
  std::atomic<std::int64_t> messages_published{0};  ///< DaemonStats::messages_published

  void setSourceState(SourceState state) { source_state_.store(state); }
  SourceState sourceState() const { return source_state_.load(); }

  /// Every counter, the segment and the source state; lock-free and allocation-free (each
  /// value is loaded on its own, not all at one instant).
  DaemonStats snapshot() const;

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
