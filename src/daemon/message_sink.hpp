#pragma once
/// \file message_sink.hpp
/// Where encoded messages go. The daemon publishes through this seam so tests can wrap the
/// real LCM sink (e.g. to attribute allocations to LCM) without touching the per-frame code.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>

namespace omnipose::daemon {

class MessageSink {
 public:
  virtual ~MessageSink() = default;
  /// Publishes `size` encoded bytes on `channel`. Returns false on failure (never throws).
  /// Called from the processing thread only.
  virtual bool publish(const std::string& channel, const std::uint8_t* data, std::size_t size) = 0;
  /// One line naming the transport, for the start-up log.
  virtual std::string describe() const = 0;
  /// Why the last publish() failed (e.g. "LCM log /var/log/run.lcm: No space left on
  /// device"), "" when the transport does not say. Valid until the next publish().
  virtual const char* lastError() const { return ""; }
};

/// Publishes over LCM. `url`: an LCM provider URL ("" = LCM's default, udpm multicast;
/// "memq://" in-process; "file://PATH?mode=w" writes an event log).
/// Throws std::runtime_error naming the URL when LCM cannot be initialised.
///
/// `file://PATH?mode=w` is written by the daemon itself with LCM's eventlog
/// writer: LCM 1.3.1's file provider ignores write errors, this sink checks every write
/// (a full disk shows in lastError() and the status; the log keeps only whole records and
/// resumes when there is room). The start-up error names the file when it cannot be opened.
///
/// What LCM 1.3.1 itself does per publish (measured by tests/daemon's allocation test):
/// udpm: no heap allocation; file:// log: none (the event is written from the caller's
/// buffer); memq://: nothing when no one subscribes, else about three per message (the
/// queued copy).
///
/// The log is created as a new file renamed over any old one (file_io.hpp): a symbolic
/// link, a FIFO, a device or a file that is not an LCM log is refused by name, never
/// written. A lock file beside it (`PATH.lock`, holding the PID) refuses a second daemon
/// writing the same log ("the log is in use by another omniposed: ...: held by process N").
std::unique_ptr<MessageSink> makeLcmSink(const std::string& url);

/// The path of a `file://PATH?mode=w` URL (the log this daemon writes itself); nullopt for
/// any other URL.
std::optional<std::string> writableLogPath(const std::string& url);

/// For `omniposed --check`, without writing anything: why the log of a `file://PATH?mode=w`
/// URL could not be written (not replaceable: checkReplaceable(), file_io.hpp), naming the
/// URL; nullopt when it could or the URL is not such a log.
std::optional<std::string> logProblem(const std::string& url);

}  // namespace omnipose::daemon
