#pragma once
/// \file message_sink.hpp
/// Where encoded messages go. The daemon publishes through this seam so tests can wrap the
/// real LCM sink (e.g. to attribute allocations to LCM) without touching the per-frame code.

#include <cstddef>
#include <cstdint>
#include <memory>
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
};

/// Publishes over LCM. `url`: an LCM provider URL ("" = LCM's default, udpm multicast;
/// "memq://" in-process; "file://PATH?mode=w" writes an event log).
/// Throws std::runtime_error naming the URL when LCM cannot be initialised.
///
/// What LCM 1.3.1 itself does per publish (measured by tests/daemon's allocation test):
/// udpm: no heap allocation; file:// (mode=w): one malloc/free per message (the log event
/// record); memq://: nothing when no one subscribes, else about three per message (the
/// queued copy).
std::unique_ptr<MessageSink> makeLcmSink(const std::string& url);

}  // namespace omnipose::daemon
