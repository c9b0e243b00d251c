#include "daemon/scheduling.hpp"

#include <linux/capability.h>
#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>

namespace omnipose::daemon {
namespace {

std::string cpuList(const std::vector<int>& cpus) {
  std::string text;
  for (int cpu : cpus) text += (text.empty() ? "" : ",") + std::to_string(cpu);
  return text;
}

/// Whether the process holds CAP_SYS_NICE in its effective set (/proc/self/status, CapEff).
bool mayRaisePriority() {
  std::FILE* f = std::fopen("/proc/self/status", "re");
  if (f == nullptr) return false;
  char line[256];
  std::uint64_t effective = 0;
  bool found = false;
  while (!found && std::fgets(line, sizeof line, f) != nullptr) {
    unsigned long long mask = 0;
    if (std::sscanf(line, "CapEff: %llx", &mask) == 1) {
      effective = mask;
      found = true;
    }
  }
  std::fclose(f);
  return found && ((effective >> CAP_SYS_NICE) & 1u) != 0;
}

std::string fifoPermission(int priority) {
  return "SCHED_FIFO at priority " + std::to_string(priority) +
         " needs the capability CAP_SYS_NICE or an RLIMIT_RTPRIO of at least " +
         std::to_string(priority) +
         " (systemd: AmbientCapabilities=CAP_SYS_NICE, or LimitRTPRIO=" +
         std::to_string(priority) + ")";
}

std::vector<std::string> cpuProblems(const std::vector<int>& cpus) {
  std::vector<std::string> problems;
  const long configured = sysconf(_SC_NPROCESSORS_CONF);
  for (int cpu : cpus) {
    if (cpu < 0 || cpu >= CPU_SETSIZE || (configured > 0 && cpu >= configured)) {
      problems.push_back("scheduling.cpus: CPU " + std::to_string(cpu) + " does not exist (this "
                         "machine has CPUs 0-" + std::to_string(configured - 1) + ")");
    }
  }
  return problems;
}

}  // namespace

std::vector<std::string> checkScheduling(const SchedulingConfig& config) {
  std::vector<std::string> problems = cpuProblems(config.cpus);
  if (config.fifo_priority > 0) {
    const int max = sched_get_priority_max(SCHED_FIFO);
    if (max > 0 && config.fifo_priority > max) {
      problems.push_back("scheduling.fifo_priority: " + std::to_string(config.fifo_priority) +
                         " is above this system's maximum, " + std::to_string(max));
    } else if (!mayRaisePriority()) {
      rlimit limit{};
      if (getrlimit(RLIMIT_RTPRIO, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY &&
          limit.rlim_cur < static_cast<rlim_t>(config.fifo_priority)) {
        problems.push_back("scheduling.fifo_priority: not permitted: " +
                           fifoPermission(config.fifo_priority) + "; this process has neither");
      }
    }
  }
  return problems;
}

std::vector<std::string> applyScheduling(const SchedulingConfig& config) {
  std::vector<std::string> problems = cpuProblems(config.cpus);
  if (!problems.empty()) return problems;
  if (!config.cpus.empty()) {
    cpu_set_t set;
    CPU_ZERO(&set);
    for (int cpu : config.cpus) CPU_SET(cpu, &set);
    if (sched_setaffinity(0, sizeof(set), &set) != 0) {
      const int error = errno;
      problems.push_back("scheduling.cpus: [" + cpuList(config.cpus) + "]: cannot run on them (" +
                         std::strerror(error) +
                         (error == EINVAL ? ": none is online and allowed to this process "
                                            "(its cgroup's cpuset)"
                                          : "") +
                         ")");
      return problems;
    }
  }
  if (config.fifo_priority > 0) {
    sched_param param{};
    param.sched_priority = config.fifo_priority;
    if (sched_setscheduler(0, SCHED_FIFO, &param) != 0) {
      const int error = errno;
      problems.push_back("scheduling.fifo_priority: " + std::to_string(config.fifo_priority) +
                         ": " + std::strerror(error) +
                         (error == EPERM ? ": " + fifoPermission(config.fifo_priority) : ""));
    }
  }
  return problems;
}

std::string describeScheduling(const SchedulingConfig& config) {
  std::string text = config.fifo_priority > 0
                         ? "SCHED_FIFO priority " + std::to_string(config.fifo_priority)
                         : std::string("normal scheduling");
  text += config.cpus.empty() ? " on every CPU" : " on CPUs " + cpuList(config.cpus);
  return text;
}

}  // namespace omnipose::daemon
