#pragma once
/// \file systemd_notify.hpp
/// sd_notify(3) for a Type=notify service: READY=1 after start-up, WATCHDOG=1 while both
/// daemon threads make progress, STATUS= lines, STOPPING=1 on shutdown. Built with
/// libsystemd when OMNIPOSE_WITH_SYSTEMD is on and pkg-config finds it
/// (OMNIPOSE_HAVE_SYSTEMD); otherwise every call is a no-op and enabled() is false.
/// Outside systemd (no NOTIFY_SOCKET) the calls do nothing either.

#include <chrono>
#include <optional>
#include <string>

namespace omnipose::daemon {

class SystemdNotifier {
 public:
  SystemdNotifier();
  /// Whether support is compiled in and the process runs under systemd's notify socket.
  bool enabled() const { return enabled_; }
  /// WatchdogSec of the unit, when the watchdog is on.
  std::optional<std::chrono::microseconds> watchdogInterval() const { return watchdog_; }

  void ready(const std::string& status);
  void watchdog();
  void status(const std::string& status);
  void stopping();

  /// Whether this build has libsystemd support.
  static bool compiledIn();

 private:
  bool enabled_ = false;
  std::optional<std::chrono::microseconds> watchdog_;
};

}  // namespace omnipose::daemon
