#include "daemon/status_board.hpp"

#include <cstdarg>
#include <cstring>

#include "daemon/wall_clock.hpp"

namespace omnipose::daemon {

const char* toString(SourceState state) {
  switch (state) {
    case SourceState::kStarting: return "starting";
    case SourceState::kStreaming: return "streaming";
    case SourceState::kReconnecting: return "reconnecting";
    case SourceState::kEnded: return "ended";
    case SourceState::kStopped: return "stopped";
  }
  return "unknown";
}

StatusBoard::StatusBoard(std::FILE* log) : log_(log) {
  const std::int64_t now = nowNs();
  capture_beat_ns_ = now;
  processor_beat_ns_ = now;
}

std::int64_t StatusBoard::nowNs() {
  return std::chrono::duration_cast<std::chrono::nanoseconds>(
             SteadyClock::now().time_since_epoch())
      .count();
}

void StatusBoard::record(const char* text) {
  std::lock_guard lock(error_mutex_);
  std::snprintf(last_error_.data(), last_error_.size(), "%s", text);
  last_error_utime_ = wallClockMicros();
  if (!log_) return;
  const std::int64_t now = nowNs();
  if (now - last_log_ns_ < std::chrono::nanoseconds(kLogInterval).count()) {
    ++suppressed_;
    return;
  }
  if (suppressed_ > 0) {
    std::fprintf(log_, "omniposed: error: %s (and %lld more since the last line)\n", text,
                 static_cast<long long>(suppressed_));
  } else {
    std::fprintf(log_, "omniposed: error: %s\n", text);
  }
  std::fflush(log_);
  suppressed_ = 0;
  last_log_ns_ = now;
}

void StatusBoard::reportError(const Error& error) { record(error.c_str()); }

void StatusBoard::reportError(const char* fmt, ...) {
  std::array<char, Error::kCapacity> text{};
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(text.data(), text.size(), fmt, args);
  va_end(args);
  record(text.data());
}

void StatusBoard::logInfo(const char* fmt, ...) {
  if (!log_) return;
  std::array<char, 512> text{};
  va_list args;
  va_start(args, fmt);
  std::vsnprintf(text.data(), text.size(), fmt, args);
  va_end(args);
  std::lock_guard lock(error_mutex_);
  std::fprintf(log_, "omniposed: %s\n", text.data());
  std::fflush(log_);
}

std::int64_t StatusBoard::lastError(char* text, std::size_t capacity) const {
  std::lock_guard lock(error_mutex_);
  if (capacity > 0) std::snprintf(text, capacity, "%s", last_error_.data());
  return last_error_utime_;
}

DaemonStats StatusBoard::snapshot() const {
  DaemonStats s;
  copyCounters(*this, s);
  s.segment = segment.load();
  s.places = places.load();
  s.source_state = sourceState();
  s.messages_published = messages_published.load();
  s.maps_saved = maps_saved.load();
  s.map_save_failures = map_save_failures.load();
  return s;
}

bool StatusBoard::alive(std::chrono::nanoseconds max_silence) const {
  const std::int64_t now = nowNs();
  const bool capture_ok =
      capture_finished_.load() || now - capture_beat_ns_.load() <= max_silence.count();
  const bool processor_ok =
      processor_finished_.load() || now - processor_beat_ns_.load() <= max_silence.count();
  return capture_ok && processor_ok;
}

}  // namespace omnipose::daemon
