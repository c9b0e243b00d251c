#include "daemon/service.hpp"

#include <pthread.h>
#include <signal.h>

#include <algorithm>
#include <cerrno>
#include <cstring>

#include "daemon/daemon.hpp"
#include "daemon/systemd_notify.hpp"

namespace omnipose::daemon {
namespace {

sigset_t stopSignals() {
  sigset_t set;
  sigemptyset(&set);
  sigaddset(&set, SIGINT);
  sigaddset(&set, SIGTERM);
  sigaddset(&set, SIGHUP);
  return set;
}

/// "received 10, processed 9, ..., segment 0, source streaming" (counters.hpp's labels).
std::string summary(const DaemonStats& s) {
  std::string text;
  text.reserve(400);
  forEachCounter(s, [&](const char* label, std::int64_t value) {
    text += label;
    text += ' ';
    text += std::to_string(value);
    text += ", ";
  });
  text += "segment " + std::to_string(s.segment) + ", source " + toString(s.source_state);
  return text;
}

}  // namespace

void blockStopSignals() {
  const sigset_t set = stopSignals();
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
}

int runService(const DaemonConfig& config, std::FILE* log) {
  // Stays blocked after return: a second signal during shutdown must not kill the
  // process half-way through writing its last messages.
  const sigset_t set = stopSignals();
  pthread_sigmask(SIG_BLOCK, &set, nullptr);

  Daemon daemon(config, log);
  SystemdNotifier notifier;
  std::fprintf(log, "omniposed: source: %s\nomniposed: output: %s (pose %s, status %s at %g Hz, "
               "diagnostics %s)\nomniposed: systemd notify: %s\n",
               daemon.sourceDescription().c_str(), daemon.sinkDescription().c_str(),
               config.lcm.pose_channel.c_str(), config.lcm.status_channel.c_str(),
               config.lcm.status_hz,
               config.lcm.fit_channel.empty() ? "off" : config.lcm.fit_channel.c_str(),
               !SystemdNotifier::compiledIn() ? "not built in"
               : notifier.enabled()           ? (notifier.watchdogInterval() ? "on, watchdog on" : "on")
                                              : "built in, not under systemd");
  std::fflush(log);

  daemon.start();
  notifier.ready("running: " + daemon.sourceDescription());

  // The watchdog is fed at half its interval, and only while both threads make progress.
  const auto watchdog = notifier.watchdogInterval();
  const auto watchdog_period = watchdog ? *watchdog / 2 : std::chrono::microseconds(0);
  auto next_ping = std::chrono::steady_clock::now();
  auto next_status_text = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  int signal_number = 0;
  while (!daemon.finished()) {
    timespec timeout{0, 100'000'000};  // 100 ms
    const int sig = sigtimedwait(&set, nullptr, &timeout);
    if (sig == SIGINT || sig == SIGTERM) {
      signal_number = sig;
      break;
    }
    if (sig == SIGHUP) {
      // No reload: a changed daemon.yaml needs a restart (the pipeline's buffers are sized
      // by it). The counters go to the log, and the daemon keeps running.
      std::fprintf(log, "omniposed: SIGHUP received: configuration not reloaded (restart to "
                   "apply changes); %s\n", summary(daemon.stats()).c_str());
      std::fflush(log);
    }
    const auto now = std::chrono::steady_clock::now();
    if (watchdog && now >= next_ping) {
      if (daemon.alive(std::chrono::duration_cast<std::chrono::nanoseconds>(watchdog_period))) {
        notifier.watchdog();
      } else {
        std::fprintf(log, "omniposed: a thread made no progress for %lld ms: not feeding the "
                     "watchdog\n", static_cast<long long>(watchdog_period.count() / 1000));
      }
      next_ping = now + watchdog_period;
    }
    if (notifier.enabled() && now >= next_status_text) {
      notifier.status(summary(daemon.stats()));
      next_status_text = now + std::chrono::seconds(10);
    }
  }
  if (signal_number != 0) {
    std::fprintf(log, "omniposed: %s received, stopping\n",
                 signal_number == SIGINT ? "SIGINT" : "SIGTERM");
    notifier.stopping();
    daemon.requestStop();
  } else {
    std::fprintf(log, "omniposed: source finished, stopping\n");
    notifier.stopping();
  }
  std::fflush(log);
  daemon.join();  // joins both threads, publishes the final status
  std::fprintf(log, "omniposed: stopped: %s\n", summary(daemon.stats()).c_str());
  std::fflush(log);
  return 0;
}

}  // namespace omnipose::daemon
