#pragma once
/// \file service.hpp
/// omniposed as a process: blocks SIGINT/SIGTERM/SIGHUP (in every thread: the mask is set before
/// the daemon's threads start and they inherit it) and waits for them with sigtimedwait()
/// on the calling thread, so no work ever runs in a signal handler; runs the Daemon;
/// notifies systemd (READY=1, WATCHDOG=1 at half of WatchdogSec while both threads make
/// progress, STATUS=, STOPPING=1); on a signal or at the end of a finite source joins both
/// threads, publishes the last status and returns 0.
///
/// Signals: SIGINT or SIGTERM stops cleanly; further SIGINT/SIGTERM during the shutdown are
/// ignored (the shutdown is bounded: both threads wake at least every 200 ms). SIGHUP does
/// not reload the configuration (the buffers are sized by it; restart to apply a change):
/// it logs one line with the counters and the daemon keeps running.

#include <cstdio>

#include "daemon/config.hpp"

namespace omnipose::daemon {

/// Runs the daemon to completion. Returns the process exit code (0: clean stop by signal
/// or end of a finite source). Start-up problems throw (std::runtime_error and
/// derived, with a message naming the file, key or device).
int runService(const DaemonConfig& config, std::FILE* log);

/// Blocks SIGINT, SIGTERM and SIGHUP in the calling thread (call first thing in main, before any
/// thread exists, so every later thread inherits the mask).
void blockStopSignals();

}  // namespace omnipose::daemon
