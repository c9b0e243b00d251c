#pragma once
/// \file scheduling.hpp
/// How the daemon's threads are scheduled: daemon.yaml's `scheduling` section
/// (SchedulingConfig, config.hpp), applied by the process's first thread before any other
/// starts, so every thread of the daemon (start-up, capture, processing, the pipeline's
/// workers) inherits it.

#include <string>
#include <vector>

#include "daemon/config.hpp"

namespace omnipose::daemon {

/// Applies `config` to the calling thread (and so to the threads it starts later): the CPU
/// affinity first, then SCHED_FIFO at config.fifo_priority when it is above 0. Returns every
/// problem, each naming the daemon.yaml key and saying what would permit it (EPERM: the
/// capability CAP_SYS_NICE or an RLIMIT_RTPRIO of at least the priority; a CPU that is not
/// online or not in the process's cgroup); empty on success. Nothing is changed for a
/// setting that failed. The default configuration changes nothing.
std::vector<std::string> applyScheduling(const SchedulingConfig& config);

/// The problems applyScheduling() would meet without changing anything (for --check):
/// CPUs that are not online, a priority above the system's maximum or above what this
/// process may use (RLIMIT_RTPRIO, unless it has CAP_SYS_NICE).
std::vector<std::string> checkScheduling(const SchedulingConfig& config);

/// "SCHED_FIFO priority 20 on CPUs 2,3" / "normal scheduling on every CPU", for the log.
std::string describeScheduling(const SchedulingConfig& config);

}  // namespace omnipose::daemon
