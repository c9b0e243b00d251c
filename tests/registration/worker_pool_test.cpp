// The worker pool (src/registration/worker_pool.hpp): every index of a job runs exactly
// once and its writes are visible to the caller when run() returns, whether the workers were
// spinning for the job (jobs back to back) or asleep on the condition variable (jobs further
// apart than the spin); within a burst the workers stay awake across gaps, and sleep after
// it; the pool is torn down cleanly in either state.
#include <gtest/gtest.h>

#include <chrono>
#include <thread>
#include <vector>

#include "registration/worker_pool.hpp"

namespace omnipose::registration {
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
  for (int threads : {1, 2, 4}) {
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
  WorkerPool pool(3);
  std::vector<int> out(55), calls(55);
  runAndCheck(pool, 0, 55, out, calls);
  long asleep = waitForSleeps(pool, 2);  // both workers fall asleep
  ASSERT_GE(asleep, 2);
  {
    WorkerPool::Burst burst(pool);  // wakes them
    std::this_thread::sleep_for(std::chrono::milliseconds(2));
    const long at_start = pool.sleeps();
    for (int job = 1; job <= 10; ++job) {
      runAndCheck(pool, job, 55, out, calls);
      std::this_thread::sleep_for(std::chrono::milliseconds(2));  // 40 times the spin
    }
    EXPECT_EQ(pool.sleeps(), at_start) << "no worker slept between the jobs of a burst";
    asleep = at_start;
  }
  EXPECT_GE(waitForSleeps(pool, asleep + 2), asleep + 2) << "both sleep again after the burst";
  runAndCheck(pool, 11, 55, out, calls);
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
}  // namespace omnipose::registration
