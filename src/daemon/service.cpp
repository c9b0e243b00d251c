#include "daemon/service.hpp"

#include <pthread.h>
#include <signal.h>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <exception>
#include <memory>
#include <stdexcept>
#include <thread>
#include <cerrno>
#include <cstring>

#include "daemon/daemon.hpp"
#include "daemon/scheduling.hpp"
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

/// "received 10, processed 9, ..., segment 0, places 3, source streaming" (counters.hpp's
/// labels).
std::string summary(const DaemonStats& s) {
  std::string text;
  text.reserve(800);
  forEachCounter(s, [&](const char* label, std::int64_t value) {
    text += label;
    text += ' ';
    text += std::to_string(value);
    text += ", ";
  });
  text += "segment " + std::to_string(s.segment) + ", places " + std::to_string(s.places) +
          ", source " + toString(s.source_state);
  if (s.maps_saved > 0 || s.map_save_failures > 0)
    text += ", maps saved " + std::to_string(s.maps_saved) + " (failed " +
            std::to_string(s.map_save_failures) + ")";
  return text;
}

const char* signalName(int sig) {
  return sig == SIGINT ? "SIGINT" : sig == SIGTERM ? "SIGTERM" : "SIGHUP";
}

/// Builds the Daemon on a thread of its own while this thread keeps answering signals: a
/// start-up that waits (a slow camera, a patient FFT plan, a filesystem that hangs) still
/// ends within 100 ms of SIGINT or SIGTERM, by exiting the process at once (the start-up
/// thread may be inside a system call that does not return; nothing it holds outlives the
/// process: locks are the kernel's, files are replaced by rename only when whole).
std::unique_ptr<Daemon> startUp(const DaemonConfig& config, std::FILE* log, const sigset_t& set,
                                const DaemonOptions& base_options) {
  StartupPhase phase{"reading the configuration"};
  DaemonOptions options = base_options;
  options.phase = &phase;
  std::unique_ptr<Daemon> daemon;
  std::exception_ptr failure;
  std::atomic<bool> done{false};
  std::thread worker([&] {
    try {
      daemon = std::make_unique<Daemon>(config, log, nullptr, nullptr, options);
    } catch (...) {
      failure = std::current_exception();
    }
    done.store(true);
  });
  while (!done.load()) {
    timespec timeout{0, 20'000'000};  // 20 ms
    const int sig = sigtimedwait(&set, nullptr, &timeout);
    if (sig == SIGINT || sig == SIGTERM) {
      std::fprintf(log, "omniposed: %s received during start-up (%s): stopping\n",
                   signalName(sig), phase.load());
      std::fflush(log);
      std::_Exit(kExitStoppedDuringStartup);
    }
    if (sig == SIGHUP) {
      std::fprintf(log, "omniposed: SIGHUP received during start-up (%s): ignored\n", phase.load());
      std::fflush(log);
    }
  }
  worker.join();
  if (failure) std::rethrow_exception(failure);
  return daemon;
}

}  // namespace

void blockStopSignals() {
  const sigset_t set = stopSignals();
  pthread_sigmask(SIG_BLOCK, &set, nullptr);
}

void unblockStopSignals() {
  const sigset_t set = stopSignals();
  pthread_sigmask(SIG_UNBLOCK, &set, nullptr);
}

int runService(const DaemonConfig& config, std::FILE* log, const DaemonOptions& options) {
  // Stays blocked after return: a second signal during shutdown must not kill the
  // process half-way through writing its last messages.
  const sigset_t set = stopSignals();
  pthread_sigmask(SIG_BLOCK, &set, nullptr);

  // Before any thread of the daemon starts: they all inherit it.
  const std::vector<std::string> refused = applyScheduling(config.scheduling);
  if (!refused.empty()) {
    std::string text = "scheduling refused:";
    for (const std::string& problem : refused) text += "\n  " + config.origin + ": " + problem;
    throw std::runtime_error(text);
  }
  std::fprintf(log, "omniposed: scheduling: %s\n", describeScheduling(config.scheduling).c_str());

  const std::unique_ptr<Daemon> started = startUp(config, log, set, options);
  Daemon& daemon = *started;
  for (const std::string& w : daemon.sourceWarnings())
    std::fprintf(log, "omniposed: warning: %s\n", w.c_str());
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
  if (const std::string imu = daemon.imuDescription(); !imu.empty())
    std::fprintf(log, "omniposed: %s\n", imu.c_str());
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
    std::fprintf(log, "omniposed: %s received, stopping\n", signalName(signal_number));
    notifier.stopping();
    daemon.requestStop();
  } else {
    std::fprintf(log, "omniposed: source finished, stopping\n");
    notifier.stopping();
  }
  std::fflush(log);
  daemon.join();  // joins both threads, publishes the final status
  const DaemonStats stats = daemon.stats();
  std::fprintf(log, "omniposed: stopped: %s\n", summary(stats).c_str());
  if (stats.publish_failures > 0 && stats.messages_published == 0) {
    std::fprintf(log, "omniposed: every message failed to publish (%lld of %lld): nothing reached "
                 "%s\n", static_cast<long long>(stats.publish_failures),
                 static_cast<long long>(stats.publish_failures), daemon.sinkDescription().c_str());
    std::fflush(log);
    return kExitNothingPublished;
  }
  std::fflush(log);
  return 0;
}

}  // namespace omnipose::daemon
