#include "daemon/systemd_notify.hpp"

#include <cstdlib>

#ifdef OMNIPOSE_HAVE_SYSTEMD
#include <systemd/sd-daemon.h>
#endif

namespace omnipose::daemon {
namespace {

/// Sends `state` (sd_notify's "KEY=VALUE" lines) to the service manager; nothing in a build
/// without systemd.
void send([[maybe_unused]] const std::string& state) {
#ifdef OMNIPOSE_HAVE_SYSTEMD
  sd_notify(0, state.c_str());
#endif
}

}  // namespace

bool SystemdNotifier::compiledIn() {
#ifdef OMNIPOSE_HAVE_SYSTEMD
  return true;
#else
  return false;
#endif
}

SystemdNotifier::SystemdNotifier() {
#ifdef OMNIPOSE_HAVE_SYSTEMD
  enabled_ = std::getenv("NOTIFY_SOCKET") != nullptr;
  std::uint64_t usec = 0;
  if (sd_watchdog_enabled(0, &usec) > 0 && usec > 0) watchdog_ = std::chrono::microseconds(usec);
#endif
}

void SystemdNotifier::ready(const std::string& status) {
  if (enabled_) send("READY=1\nSTATUS=" + status);
}

void SystemdNotifier::watchdog() {
  if (watchdog_) send("WATCHDOG=1");
}

void SystemdNotifier::status(const std::string& status) {
  if (enabled_) send("STATUS=" + status);
}

void SystemdNotifier::stopping() {
  if (enabled_) send("STOPPING=1");
}

}  // namespace omnipose::daemon
