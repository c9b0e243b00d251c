#pragma once
/// \file service.hpp
/// omniposed as a process: blocks SIGINT/SIGTERM/SIGHUP (in every thread: the mask is set before
/// the daemon's threads start and they inherit it) and waits for them with sigtimedwait()
/// on the calling thread, so no work ever runs in a signal handler; runs the Daemon;
/// notifies systemd (READY=1, WATCHDOG=1 at half of WatchdogSec while both threads make
/// progress, STATUS=, STOPPING=1); on a signal or at the end of a finite source joins both
/// threads, publishes the last status and returns 0.
///
/// Signals: SIGINT or SIGTERM stops cleanly, during start-up too (runService()); further
/// SIGINT/SIGTERM during the shutdown are ignored (the shutdown is bounded: both threads wake
/// at least every 200 ms). SIGHUP does not reload the configuration (the buffers are sized by
/// it; restart to apply a change): it logs one line with the counters and the daemon keeps
/// running.

#include <cstdio>

#include "daemon/config.hpp"
#include "daemon/daemon.hpp"

namespace omnipose::daemon {

/// Exit code of a run in which every message failed to publish (an LCM log on a device that
/// refuses every write, a transport that never worked): the daemon ran, nothing reached
/// the controller.
inline constexpr int kExitNothingPublished = 3;
/// Exit code when SIGINT or SIGTERM came during start-up: the process stops at once, as it
/// does after a clean stop (one log line says in which phase).
inline constexpr int kExitStoppedDuringStartup = 0;

/// Runs the daemon to completion. Start-up runs on a thread of its own while the calling
/// thread answers signals, so SIGINT/SIGTERM end the process within 100 ms in every
/// phase: then the process exits (std::_Exit, kExitStoppedDuringStartup) from here after
/// one log line naming the phase. Returns the process exit code: 0 after a clean stop by
/// signal or at the end of a finite source, kExitNothingPublished when messages were
/// published and every one failed. Start-up problems throw (std::runtime_error and
/// derived, with a message naming the file, key or device). `options`: DaemonOptions
/// other than the defaults (tests).
int runService(const DaemonConfig& config, std::FILE* log, const DaemonOptions& options = {});

/// Blocks SIGINT, SIGTERM and SIGHUP in the calling thread (call first thing in main, before any
/// thread exists, so every later thread inherits the mask).
void blockStopSignals();
/// Undoes blockStopSignals() in the calling thread (SIGINT/SIGTERM then end the process).
void unblockStopSignals();

}  // namespace omnipose::daemon
