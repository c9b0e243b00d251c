// The worker pool (src/runtime/worker_pool.hpp): every index of a job runs exactly
// once and its writes are visible to the caller when run() returns, whether the workers were
// spinning for the job (jobs back to back) or asleep on the condition variable (jobs further
// apart than the spin); within a burst the workers stay awake across gaps, and sleep after
// it; the pool is torn down cleanly in either state. A worker that does not run (the kernel
// gave its core to another process) holds no job up: the others take its share; one that
// holds frames up inside its indices is left out of the next frames (WorkerCountTuner).
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <thread>
#include <vector>

#include "runtime/worker_pool.hpp"

namespace omnipose::runtime {
namespace {

/// Runs one job of `count` indices that writes job + index into out[index] and counts the
/// workers' calls; checks every index once, with the job's value.
void runAndCheck(WorkerPool& pool, int job, int count, std::vector<int>& out,
                 std::vector<int>& calls) {
  std::fill(calls.begin(), calls.end(), 0);
  auto task = [&](int worker, int index) {
    ASSERT_GE(worker, 0);
    ASSERT_LT(worker, pool.size());
    out[index] = job + index;
    ++calls[index];  // each index belongs to one call, so no two workers write one entry
  };
  pool.run(count, task);
  for (int i = 0; i < count; ++i) {
    ASSERT_EQ(calls[i], 1) << "job " << job << " index " << i;
    ASSERT_EQ(out[i], job + i) << "job " << job << " index " << i;
  }
}

TEST(WorkerPool, BackToBackJobsRunEveryIndexOnce) {
  // 8 threads on the 2-core test machine: workers arrive late, after every index of a job was
  // claimed, and must claim nothing of the next one.
  for (int threads : {1, 2, 4, 8}) {
    WorkerPool pool(threads);
    ASSERT_EQ(pool.size(), threads);
    std::vector<int> out(97), calls(97);
    for (int job = 0; job < 2000; ++job) runAndCheck(pool, job, 1 + job % 97, out, calls);
  }
}

TEST(WorkerPool, JobsAfterTheWorkersFellAsleepRunEveryIndexOnce) {
  WorkerPool pool(3);
  std::vector<int> out(55), calls(55);
  for (int job = 0; job < 20; ++job) {
    runAndCheck(pool, job, 55, out, calls);
    std::this_thread::sleep_for(std::chrono::milliseconds(2));  // far beyond the spin
  }
}

/// Waits (up to 10 s, for loaded machines) until the pool's workers went to sleep at least
/// `count` times in all; returns the count then.
long waitForSleeps(const WorkerPool& pool, long count) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
  while (pool.sleeps() < count && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  return pool.sleeps();
}

TEST(WorkerPool, WorkersStayAwakeThroughABurstAndSleepAfterIt) {
  // One worker beside the caller: on the 2-core test machine each has a core, unless other
  // processes take one; a worker that arrives after a job was wholly claimed (its core was
  // taken) may sleep between the jobs of that burst, and only then.
  WorkerPool pool(2);
  std::vector<int> out(55), calls(55);
  runAndCheck(pool, 0, 55, out, calls);
  long asleep = waitForSleeps(pool, 1);  // the worker falls asleep
  ASSERT_GE(asleep, 1);
  {
    WorkerPool::Burst burst(pool);  // wakes it
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
    const long at_start = pool.sleeps();
    const long late_at_start = pool.lateArrivals();
    for (int job = 1; job <= 10; ++job) {
      runAndCheck(pool, job, 55, out, calls);
      std::this_thread::sleep_for(std::chrono::milliseconds(2));  // 40 times the spin
    }
    if (pool.lateArrivals() == late_at_start) {
      EXPECT_EQ(pool.sleeps(), at_start) << "no worker slept between the jobs of a burst";
    }
  }
  asleep = pool.sleeps();
  runAndCheck(pool, 11, 55, out, calls);
  EXPECT_GE(waitForSleeps(pool, asleep + 1), asleep + 1) << "it sleeps again after the burst";
}

// A thread held in a signal handler stands for a worker the kernel does not schedule.
std::atomic<int> g_held{0};
std::atomic<bool> g_release{false};

void holdThread(int) {
  g_held.fetch_add(1);
  const timespec pause{0, 1'000'000};
  for (int ms = 0; ms < 5000 && !g_release.load(); ++ms) nanosleep(&pause, nullptr);
  g_held.fetch_sub(1);
}

/// The ids of this process's threads other than the calling one.
std::vector<pid_t> otherThreads() {
  std::vector<pid_t> ids;
  const pid_t self = static_cast<pid_t>(syscall(SYS_gettid));
  for (const auto& entry : std::filesystem::directory_iterator("/proc/self/task")) {
    const pid_t id = std::stoi(entry.path().filename().string());
    if (id != self) ids.push_back(id);
  }
  return ids;
}

TEST(WorkerPool, AWorkerThatDoesNotRunHoldsNoJobUp) {
  struct sigaction action{};
  action.sa_handler = holdThread;
  sigemptyset(&action.sa_mask);
  struct sigaction previous{};
  ASSERT_EQ(sigaction(SIGUSR1, &action, &previous), 0);
  for (const bool in_burst : {false, true}) {
    g_release = false;
    const std::vector<pid_t> before = otherThreads();
    WorkerPool pool(3);
    std::vector<int> out(64), calls(64);
    runAndCheck(pool, 0, 64, out, calls);
    std::vector<pid_t> workers;
    for (pid_t id : otherThreads())
      if (std::find(before.begin(), before.end(), id) == before.end()) workers.push_back(id);
    ASSERT_EQ(workers.size(), 2u);
    // Hold one worker, between jobs (it holds no index), until released or 5 s passed.
    ASSERT_EQ(syscall(SYS_tgkill, getpid(), workers[0], SIGUSR1), 0);
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(5);
    while (g_held.load() == 0 && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::microseconds(100));
    ASSERT_EQ(g_held.load(), 1);
    {
      auto burst = in_burst ? std::optional<WorkerPool::Burst>(std::in_place, pool) : std::nullopt;
      for (int job = 1; job <= 200; ++job) runAndCheck(pool, job, 64, out, calls);
    }
    EXPECT_EQ(g_held.load(), 1) << "the 200 jobs waited for the held worker (burst " << in_burst
                                << ")";
    g_release = true;
    while (g_held.load() != 0) std::this_thread::sleep_for(std::chrono::microseconds(100));
    runAndCheck(pool, 201, 64, out, calls);  // the released worker joins in again
  }
  ASSERT_EQ(sigaction(SIGUSR1, &previous, nullptr), 0);
}

TEST(WorkerPool, AWorkerThatHoldsFramesUpIsLeftOut) {
  // Worker 1 stands for a worker whose core another process takes: every index it claims
  // keeps it 3 ms, while the caller runs an index in 20 us. Within some frames (bursts: the
  // tuner's first frames and a probe, more when a loaded test machine keeps the probe from
  // telling) the frames run on the caller alone, and every frame does every index once.
  WorkerPool pool(2);
  ASSERT_EQ(pool.activeWorkers(), 2);
  std::vector<int> out(64), calls(64);
  std::atomic<int> on_worker_1{0};
  auto task = [&](int worker, int index) {
    if (worker == 1) {
      on_worker_1.fetch_add(1);
      std::this_thread::sleep_for(std::chrono::milliseconds(3));
    } else {
      const auto until = std::chrono::steady_clock::now() + std::chrono::microseconds(20);
      while (std::chrono::steady_clock::now() < until) {
      }
    }
    out[index] = index;
    ++calls[index];
  };
  // Left out for good: a probe's frames alternate, so several frames in a row on the caller
  // alone mean the probe kept that count.
  int frames = 0, alone_in_a_row = 0;
  for (; frames < 400 && alone_in_a_row < 3; ++frames) {
    alone_in_a_row = pool.activeWorkers() == 1 ? alone_in_a_row + 1 : 0;
    WorkerPool::Burst burst(pool);
    std::fill(calls.begin(), calls.end(), 0);
    pool.run(64, task);
    for (int i = 0; i < 64; ++i) ASSERT_EQ(calls[i], 1) << "frame " << frames << " index " << i;
  }
  EXPECT_EQ(alone_in_a_row, 3) << "after " << frames << " frames";
  EXPECT_EQ(pool.activeWorkers(), 1);
  // The caller waited for the slow worker in the frames it took part in, and only in those.
  EXPECT_GT(pool.waitedBursts(), 0);
  EXPECT_LE(pool.waitedBursts(), frames - 3);
  EXPECT_GT(on_worker_1.load(), 0) << "the worker took part at first";
  // Left out: of the next frames (fewer than a lost probe's hold), at most one probe's run on
  // both workers (a loaded test machine may move the frame time enough to probe at once).
  int with_both = 0;
  for (int frame = 0; frame < 10; ++frame) {
    if (pool.activeWorkers() == 2) ++with_both;
    WorkerPool::Burst burst(pool);
    std::fill(calls.begin(), calls.end(), 0);
    pool.run(64, task);
    for (int i = 0; i < 64; ++i) ASSERT_EQ(calls[i], 1) << "frame " << frame << " index " << i;
  }
  EXPECT_LE(with_both, WorkerCountTuner::kProbeFrames);
}

TEST(WorkerPool, ACallerAloneNeverWaits) {
  WorkerPool pool(1);
  std::vector<int> out(64), calls(64);
  for (int frame = 0; frame < 5; ++frame) {
    WorkerPool::Burst burst(pool);
    runAndCheck(pool, frame, 64, out, calls);
  }
  EXPECT_EQ(pool.waits(), 0);
  EXPECT_EQ(pool.waitedBursts(), 0);
}

TEST(WorkerPool, EmptyAndSingleJobsRunOnTheCaller) {
  WorkerPool pool(2);
  int runs = 0;
  auto task = [&](int worker, int) {
    EXPECT_EQ(worker, 0);
    ++runs;
  };
  pool.run(0, task);
  EXPECT_EQ(runs, 0);
  pool.run(1, task);
  EXPECT_EQ(runs, 1);
}

TEST(WorkerPool, TearsDownWhileWorkersSpinOrSleep) {
  for (int round = 0; round < 50; ++round) {
    WorkerPool idle(2);  // destroyed before any job
  }
  std::vector<int> out(8), calls(8);
  for (int round = 0; round < 50; ++round) {
    WorkerPool spinning(2);
    runAndCheck(spinning, round, 8, out, calls);  // destroyed right after: workers spinning
  }
  for (int round = 0; round < 20; ++round) {
    WorkerPool bursting(2);
    WorkerPool::Burst burst(bursting);  // closed just before the pool goes, workers spinning
    runAndCheck(bursting, round, 8, out, calls);
  }
  WorkerPool sleeping(2);
  runAndCheck(sleeping, 0, 8, out, calls);
  std::this_thread::sleep_for(std::chrono::milliseconds(2));  // destroyed asleep
  EXPECT_GE(WorkerPool::onlineCores(), 1);
}

}  // namespace
}  // namespace omnipose::runtime
