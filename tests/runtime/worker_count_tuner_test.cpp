// How many workers take part (src/runtime/worker_count_tuner.hpp), on modelled machines:
// idle, every worker always; a worker that the machine keeps from running, fewer and stays so;
// a load under which fewer workers are slower, at most one probe frame in many; the load gone,
// all workers again; noisy frame times, no wandering.
#include <gtest/gtest.h>

#include <functional>
#include <limits>
#include <random>

#include "runtime/worker_count_tuner.hpp"

namespace omnipose::runtime {
namespace {

/// A machine: the wall time and the wait of one frame run on `count` workers.
struct Frame {
  double seconds;
  double waited;
};
using Machine = std::function<Frame(int count)>;

struct Tally {
  std::vector<int> frames_at;  ///< frames run per count (index count)
  int last = 0;                ///< the count of the last frame
  int changes = 0;             ///< frames run on another count than the one before
};

Tally runFrames(WorkerCountTuner& tuner, int frames, const Machine& machine) {
  Tally run;
  run.frames_at.assign(64, 0);
  int previous = tuner.active();
  for (int f = 0; f < frames; ++f) {
    const int count = tuner.active();
    ++run.frames_at[count];
    if (count != previous) ++run.changes;
    previous = count;
    const Frame frame = machine(count);
    const int next = tuner.frameEnded(frame.seconds, frame.waited);
    EXPECT_EQ(next, tuner.active());
    run.last = count;
  }
  return run;
}

TEST(WorkerCountTuner, AnIdleMachineKeepsEveryWorker) {
  for (int workers : {2, 4, 8}) {
    WorkerCountTuner tuner(workers);
    ASSERT_EQ(tuner.active(), workers);
    // Idle: the work divides, the caller waits ~3 % of the frame for the last indices.
    const Tally run = runFrames(tuner, 5000, [&](int count) {
      return Frame{0.024 / count, 0.03 * 0.024 / count};
    });
    EXPECT_EQ(run.frames_at[workers], 5000) << workers << " workers";
  }
}

TEST(WorkerCountTuner, AStarvedWorkerIsLeftOutAndStaysOut) {
  // Two workers, one of them behind a higher-priority process: with it the frame takes 30 ms
  // of which 12 waiting for it, the caller alone 20 ms.
  WorkerCountTuner tuner(2);
  const Machine starved = [](int count) {
    return count == 2 ? Frame{0.030, 0.012} : Frame{0.020, 0.0};
  };
  const Tally start = runFrames(tuner, 20, starved);
  EXPECT_EQ(tuner.active(), 1);
  EXPECT_LE(start.frames_at[2], 8) << "left out within a few frames";
  const Tally steady = runFrames(tuner, 3000, starved);
  EXPECT_EQ(steady.last, 1);
  // Probes of two workers lose, then come less and less often: at most one frame in
  // kMaxHoldFrames after the first few.
  EXPECT_LE(steady.frames_at[2], 3000 / WorkerCountTuner::kMaxHoldFrames + 5);
}

TEST(WorkerCountTuner, WaitingAloneDoesNotLeaveOutAWorkerThatHelps) {
  // Two busy processes on two cores: the caller waits 15 % of the 30 ms frame, but alone it
  // takes 40 ms. The probes of one worker lose and become rare.
  WorkerCountTuner tuner(2);
  const Tally run = runFrames(tuner, 3000, [](int count) {
    return count == 2 ? Frame{0.030, 0.0045} : Frame{0.040, 0.0};
  });
  EXPECT_EQ(run.last, 2);
  EXPECT_LE(run.frames_at[1], 3000 / WorkerCountTuner::kMaxHoldFrames + 5);
}

TEST(WorkerCountTuner, AllWorkersReturnWhenTheLoadIsGone) {
  WorkerCountTuner tuner(2);
  runFrames(tuner, 3000, [](int count) {
    return count == 2 ? Frame{0.030, 0.012} : Frame{0.020, 0.0};
  });
  ASSERT_EQ(tuner.active(), 1);
  // Idle again: two workers take 12 ms, one 20 ms.
  const Machine idle = [](int count) {
    return count == 2 ? Frame{0.012, 0.0004} : Frame{0.020, 0.0};
  };
  const Tally back = runFrames(tuner, WorkerCountTuner::kMaxHoldFrames + 10, idle);
  EXPECT_EQ(back.last, 2);
  const Tally after = runFrames(tuner, 3000, idle);
  EXPECT_EQ(after.frames_at[2], 3000);
}

TEST(WorkerCountTuner, FindsTheBestCountAmongMany) {
  // Four workers, one core taken by another process: the worker sharing it makes the others
  // wait. Three workers are best: 4 -> 3, and neither 2 nor 4 is kept.
  WorkerCountTuner tuner(4);
  const Tally run = runFrames(tuner, 3000, [](int count) {
    switch (count) {
      case 4: return Frame{0.020, 0.008};
      case 3: return Frame{0.012, 0.0004};
      case 2: return Frame{0.016, 0.0004};
      default: return Frame{0.030, 0.0};
    }
  });
  EXPECT_EQ(run.last, 3);
  EXPECT_GE(run.frames_at[3], 2950);
  EXPECT_EQ(run.frames_at[1], 0);
}

TEST(WorkerCountTuner, NoisyFrameTimesDoNotMakeItWander) {
  // Idle, frame times +-15 % (content, caches, interrupts), waits 0-8 %: all workers.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> noise(0.85, 1.15), wait(0.0, 0.08);
  WorkerCountTuner tuner(2);
  const Tally run = runFrames(tuner, 5000, [&](int count) {
    const double s = (count == 2 ? 0.012 : 0.020) * noise(rng);
    return Frame{s, count == 2 ? wait(rng) * s : 0.0};
  });
  EXPECT_EQ(run.frames_at[2], 5000);
}

TEST(WorkerCountTuner, IgnoresFramesWithoutATime) {
  WorkerCountTuner tuner(2);
  for (int f = 0; f < 100; ++f) {
    EXPECT_EQ(tuner.frameEnded(0.0, 0.0), 2);
    EXPECT_EQ(tuner.frameEnded(-1.0, 0.5), 2);
    EXPECT_EQ(tuner.frameEnded(std::numeric_limits<double>::quiet_NaN(), 0.0), 2);
  }
  WorkerCountTuner single(1);
  EXPECT_EQ(single.frameEnded(0.03, 0.02), 1);
}

}  // namespace
}  // namespace omnipose::runtime
