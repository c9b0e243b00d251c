// Runs a program with an EEVDF request ("slice") of its own: sched_setattr() with
// sched_runtime on the calling SCHED_OTHER thread (Linux 6.12 and later, no privilege
// needed; the niceness is kept), then exec. Every thread the program starts inherits it.
// docs/PERFORMANCE.md section 6, "The kernel's latency hint, and what sets the tail".
//
// Usage: omnipose-experiment-sched-slice RUNTIME_NS PROGRAM [ARGS...]
//   RUNTIME_NS 0 restores the kernel's default slice; the kernel clamps others to 0.1-100 ms.
// With tools/realtime_check.sh: a directory D/bin holding omnipose-synth and omnipose-listen
// (symbolic links to build/bin's) and an executable script omniposed that runs
//   exec build/bin/omnipose-experiment-sched-slice 3000000 "$PWD"/build/bin/omniposed "$@"
// (absolute paths), then BUILD_DIR=D tools/realtime_check.sh --load 2 30 300.
#include <sys/syscall.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace {

// The kernel's struct sched_attr (glibc has no wrapper for the system call).
struct SchedAttr {
  std::uint32_t size;
  std::uint32_t sched_policy;
  std::uint64_t sched_flags;
  std::int32_t sched_nice;
  std::uint32_t sched_priority;
  std::uint64_t sched_runtime;
  std::uint64_t sched_deadline;
  std::uint64_t sched_period;
  std::uint32_t sched_util_min;
  std::uint32_t sched_util_max;
};

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: omnipose-experiment-sched-slice RUNTIME_NS PROGRAM [ARGS...]\n");
    return 2;
  }
  char* end = nullptr;
  const unsigned long long runtime_ns = std::strtoull(argv[1], &end, 10);
  if (end == argv[1] || *end != '\0') {
    std::fprintf(stderr, "sched-slice: RUNTIME_NS '%s' is not a number of nanoseconds\n", argv[1]);
    return 2;
  }
  SchedAttr attr{};
  if (syscall(SYS_sched_getattr, 0, &attr, sizeof attr, 0) != 0) {
    std::fprintf(stderr, "sched-slice: sched_getattr: %s\n", std::strerror(errno));
    return 1;
  }
  attr.size = sizeof attr;
  attr.sched_runtime = runtime_ns;
  if (syscall(SYS_sched_setattr, 0, &attr, 0) != 0) {
    std::fprintf(stderr, "sched-slice: sched_setattr(runtime %llu ns): %s\n", runtime_ns,
                 std::strerror(errno));
    return 1;
  }
  execv(argv[2], argv + 2);
  std::fprintf(stderr, "sched-slice: %s: %s\n", argv[2], std::strerror(errno));
  return 1;
}
