#include "daemon/systemd_notify.hpp"

#include <cstdlib>

#ifdef OMNIPOSE_HAVE_SYSTEMD
#include <systemd/sd-daemon.h>
#endif

namespace omnipose::daemon {

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

void SystemdNotifier::ready([[maybe_unused]] const std::string& status) {
#ifdef OMNIPOSE_HAVE_SYSTEMD
  if (enabled_) sd_notifyf(0, "READY=1\nSTATUS=%s", status.c_str());
#endif
}

void SystemdNotifier::watchdog() {
#ifdef OMNIPOSE_HAVE_SYSTEMD
  if (watchdog_) sd_notify(0, "WATCHDOG=1");
#endif
}

void SystemdNotifier::status([[maybe_unused]] const std::string& status) {
#ifdef OMNIPOSE_HAVE_SYSTEMD
  if (enabled_) sd_notifyf(0, "STATUS=%s", status.c_str());
#endif
}

void SystemdNotifier::stopping() {
#ifdef OMNIPOSE_HAVE_SYSTEMD
  if (enabled_) sd_notify(0, "STOPPING=1");
#endif
}

}  // namespace omnipose::daemon
