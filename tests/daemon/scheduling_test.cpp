// daemon.yaml's scheduling section applied (src/daemon/scheduling.hpp): the default changes
// nothing; CPUs and SCHED_FIFO are applied to the calling thread and inherited by the threads
// it starts; without the permission, or with a CPU that does not exist, the refusal names the
// key and what would permit it. Each case that changes the scheduling runs in a child process.
#include "daemon/scheduling.hpp"

#include <gtest/gtest.h>
#include <linux/capability.h>
#include <sched.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdio>
#include <functional>
#include <string>
#include <thread>

#include "runtime/worker_pool.hpp"

namespace omnipose::daemon {
namespace {

bool mentions(const std::vector<std::string>& problems, const std::string& needle) {
  for (const auto& p : problems)
    if (p.find(needle) != std::string::npos) return true;
  return false;
}

/// Runs `body` in a child process; returns its exit status (body's return value), -1 if it
/// did not exit normally.
int inChild(const std::function<int()>& body) {
  std::fflush(nullptr);
  const pid_t pid = fork();
  if (pid == 0) _exit(body());
  int status = 0;
  if (pid < 0 || waitpid(pid, &status, 0) != pid || !WIFEXITED(status)) return -1;
  return WEXITSTATUS(status);
}

/// Drops CAP_SYS_NICE from the calling process's effective and permitted sets.
bool dropSysNice() {
  __user_cap_header_struct header{_LINUX_CAPABILITY_VERSION_3, 0};
  __user_cap_data_struct data[2]{};
  if (syscall(SYS_capget, &header, data) != 0) return false;
  data[CAP_SYS_NICE / 32].effective &= ~(1u << (CAP_SYS_NICE % 32));
  data[CAP_SYS_NICE / 32].permitted &= ~(1u << (CAP_SYS_NICE % 32));
  return syscall(SYS_capset, &header, data) == 0;
}

TEST(Scheduling, TheDefaultChangesNothing) {
  cpu_set_t before;
  ASSERT_EQ(sched_getaffinity(0, sizeof(before), &before), 0);
  const int policy = sched_getscheduler(0);
  EXPECT_TRUE(applyScheduling(SchedulingConfig{}).empty());
  EXPECT_TRUE(checkScheduling(SchedulingConfig{}).empty());
  cpu_set_t after;
  ASSERT_EQ(sched_getaffinity(0, sizeof(after), &after), 0);
  EXPECT_TRUE(CPU_EQUAL(&before, &after));
  EXPECT_EQ(sched_getscheduler(0), policy);
  EXPECT_EQ(describeScheduling(SchedulingConfig{}), "normal scheduling on every CPU");
}

TEST(Scheduling, ACpuThatDoesNotExistIsRefusedAndNothingChanges) {
  SchedulingConfig config;
  config.cpus = {0, 4000};
  const auto problems = applyScheduling(config);
  EXPECT_TRUE(mentions(problems, "scheduling.cpus: CPU 4000 does not exist")) << problems.size();
  EXPECT_TRUE(mentions(checkScheduling(config), "scheduling.cpus: CPU 4000 does not exist"));
  cpu_set_t now;
  ASSERT_EQ(sched_getaffinity(0, sizeof(now), &now), 0);
  EXPECT_EQ(CPU_COUNT(&now), runtime::WorkerPool::onlineCores()) << "the affinity is unchanged";
}

TEST(Scheduling, CpusAreAppliedAndInheritedByLaterThreads) {
  SchedulingConfig config;
  config.cpus = {0};
  EXPECT_EQ(describeScheduling(config), "normal scheduling on CPUs 0");
  const int status = inChild([&] {
    if (!applyScheduling(config).empty()) return 2;
    int inherited = -1;
    std::thread later([&] {
      cpu_set_t set;
      if (sched_getaffinity(0, sizeof(set), &set) == 0)
        inherited = CPU_COUNT(&set) == 1 && CPU_ISSET(0, &set) ? 1 : 0;
    });
    later.join();
    return inherited == 1 ? 0 : 3;
  });
  EXPECT_EQ(status, 0) << "2: refused, 3: a later thread did not inherit CPU 0 alone";
}

TEST(Scheduling, FifoIsAppliedAndInheritedWhenPermitted) {
  SchedulingConfig config;
  config.fifo_priority = 1;
  EXPECT_EQ(describeScheduling(config), "SCHED_FIFO priority 1 on every CPU");
  const int status = inChild([&] {
    const auto problems = applyScheduling(config);
    if (!problems.empty()) {
      std::fprintf(stderr, "%s\n", problems[0].c_str());
      return 77;
    }
    int inherited = -1;
    std::thread later([&] { inherited = sched_getscheduler(0); });
    later.join();
    return sched_getscheduler(0) == SCHED_FIFO && inherited == SCHED_FIFO ? 0 : 3;
  });
  if (status == 77) GTEST_SKIP() << "this machine does not permit SCHED_FIFO (printed above)";
  EXPECT_EQ(status, 0) << "3: not SCHED_FIFO, or a later thread did not inherit it";
}

TEST(Scheduling, WithoutThePermissionFifoIsRefusedNamingWhatWouldPermitIt) {
  SchedulingConfig config;
  config.fifo_priority = 10;
  const int status = inChild([&] {
    const rlimit none{0, 0};
    if (setrlimit(RLIMIT_RTPRIO, &none) != 0 || (geteuid() == 0 && !dropSysNice())) return 2;
    const auto checked = checkScheduling(config);
    const auto refused = applyScheduling(config);
    for (const auto* problems : {&checked, &refused}) {
      if (!mentions(*problems, "scheduling.fifo_priority") ||
          !mentions(*problems, "CAP_SYS_NICE") || !mentions(*problems, "LimitRTPRIO=10"))
        return 3;
    }
    return sched_getscheduler(0) == SCHED_FIFO ? 4 : 0;
  });
  EXPECT_EQ(status, 0) << "2: could not drop the permission, 3: the message, 4: applied anyway";
}

}  // namespace
}  // namespace omnipose::daemon
