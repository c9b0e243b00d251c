// How many workers take part (src/runtime/worker_count_tuner.hpp), on modelled machines:
// idle, every worker but for rare probe frames; a worker that makes the frame slower, fewer and
// stays so; a load under which fewer workers are slower, at most a few probe frames in many; a
// load that appears, met within a few frames; the load gone, all workers again; noisy frame
// times and odd frames, no wandering.
#include <gtest/gtest.h>

#include <functional>
#include <limits>
#include <random>

#include "runtime/worker_count_tuner.hpp"

namespace omnipose::runtime {
namespace {

/// A machine: the wall time of one frame run on `count` workers, seconds.
using Machine = std::function<double(int count)>;

struct Tally {
  std::vector<int> frames_at;  ///< frames run per count (index count)
  int last = 0;                ///< the count of the last frame
};

Tally runFrames(WorkerCountTuner& tuner, int frames, const Machine& machine) {
  Tally run;
  run.frames_at.assign(64, 0);
  for (int f = 0; f < frames; ++f) {
    const int count = tuner.active();
    ++run.frames_at[count];
    const int next = tuner.frameEnded(machine(count));
    EXPECT_EQ(next, tuner.active());
    run.last = count;
  }
  return run;
}

/// The most frames a steady machine runs on a losing count in `frames`: each lost probe is
/// kProbeFrames frames, and after the first few they come once in kMaxHoldFrames.
int probeBudget(int frames) {
  return WorkerCountTuner::kProbeFrames * (frames / WorkerCountTuner::kMaxHoldFrames + 6);
}

TEST(WorkerCountTuner, AnIdleMachineKeepsEveryWorker) {
  for (int workers : {2, 4, 8}) {
    WorkerCountTuner tuner(workers);
    ASSERT_EQ(tuner.active(), workers);
    const Tally run = runFrames(tuner, 5000, [&](int count) { return 0.024 / count; });
    EXPECT_GE(run.frames_at[workers], 5000 - probeBudget(5000)) << workers << " workers";
    EXPECT_EQ(tuner.current(), workers);
    EXPECT_EQ(run.last, workers);
  }
}

TEST(WorkerCountTuner, AWorkerThatSlowsTheFrameIsLeftOutAndStaysOut) {
  // Two workers on a core shared with a busy process: with both the frame takes 30 ms, the
  // caller alone 20 ms.
  WorkerCountTuner tuner(2);
  const Machine shared = [](int count) { return count == 2 ? 0.030 : 0.020; };
  const Tally start = runFrames(tuner, 20, shared);
  EXPECT_EQ(tuner.current(), 1);
  EXPECT_LE(start.frames_at[2], WorkerCountTuner::kRecentFrames + WorkerCountTuner::kProbeFrames) << "left out at once";
  const Tally steady = runFrames(tuner, 3000, shared);
  EXPECT_EQ(steady.last, 1);
  EXPECT_LE(steady.frames_at[2], probeBudget(3000));
}

TEST(WorkerCountTuner, AWorkerThatHelpsUnderLoadIsKept) {
  // Two busy processes on two cores: two workers take 30 ms, the caller alone 40 ms.
  WorkerCountTuner tuner(2);
  const Tally run = runFrames(tuner, 3000, [](int count) { return count == 2 ? 0.030 : 0.040; });
  EXPECT_EQ(run.last, 2);
  EXPECT_LE(run.frames_at[1], probeBudget(3000));
}

TEST(WorkerCountTuner, ALoadThatAppearsIsMetWithinAFewFrames) {
  // Idle long enough for the probes to have backed off to the longest hold; then a busy
  // process starts and two workers become slower than one (13 against 7.4 ms, as measured
  // with realtime_check.sh --load 1).
  WorkerCountTuner tuner(2);
  runFrames(tuner, 3000, [](int count) { return count == 2 ? 0.0067 : 0.0076; });
  ASSERT_EQ(tuner.current(), 2);
  const Machine loaded = [](int count) { return count == 2 ? 0.013 : 0.0074; };
  const Tally met = runFrames(tuner, 20, loaded);
  EXPECT_EQ(tuner.current(), 1);
  EXPECT_LE(met.frames_at[2], 2 * WorkerCountTuner::kRecentFrames + 2 * WorkerCountTuner::kProbeFrames);
}

TEST(WorkerCountTuner, AllWorkersReturnWhenTheLoadIsGone) {
  WorkerCountTuner tuner(2);
  runFrames(tuner, 3000, [](int count) { return count == 2 ? 0.030 : 0.020; });
  ASSERT_EQ(tuner.current(), 1);
  // Idle again: two workers take 12 ms, one 20 ms.
  const Machine idle = [](int count) { return count == 2 ? 0.012 : 0.020; };
  const Tally back = runFrames(tuner, WorkerCountTuner::kMaxHoldFrames + 10, idle);
  EXPECT_EQ(back.last, 2);
  const Tally after = runFrames(tuner, 3000, idle);
  EXPECT_GE(after.frames_at[2], 3000 - probeBudget(3000));
  EXPECT_EQ(tuner.current(), 2);
}

TEST(WorkerCountTuner, FindsTheBestCountAmongMany) {
  // Four workers, one core taken by another process: the worker sharing it makes the others
  // wait. Three workers are best: 4 -> 3, and neither 2 nor 4 is kept.
  WorkerCountTuner tuner(4);
  const Tally run = runFrames(tuner, 3000, [](int count) {
    switch (count) {
      case 4: return 0.020;
      case 3: return 0.012;
      case 2: return 0.016;
      default: return 0.030;
    }
  });
  EXPECT_EQ(run.last, 3);
  EXPECT_GE(run.frames_at[3], 3000 - 2 * probeBudget(3000));
  EXPECT_EQ(run.frames_at[1], 0);
}

TEST(WorkerCountTuner, NoisyFrameTimesDoNotMakeItWander) {
  // Idle, frame times +-15 % (content, caches, interrupts): all workers.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> noise(0.85, 1.15);
  WorkerCountTuner tuner(2);
  const Tally run = runFrames(tuner, 5000, [&](int count) {
    return (count == 2 ? 0.012 : 0.020) * noise(rng);
  });
  EXPECT_GE(run.frames_at[2], 5000 - probeBudget(5000));
  EXPECT_EQ(tuner.current(), 2);
}

TEST(WorkerCountTuner, AnOddFrameInAProbeDoesNotDecideIt) {
  // Every fifth frame takes four times as long (a gap bridged, a keyframe searched); one worker
  // is never faster, whichever frame of a probe the odd one falls on.
  WorkerCountTuner tuner(2);
  int frame = 0;
  const Tally run = runFrames(tuner, 5000, [&](int count) {
    const double base = count == 2 ? 0.012 : 0.020;
    return ++frame % 5 == 0 ? 4.0 * base : base;
  });
  EXPECT_GE(run.frames_at[2], 5000 - probeBudget(5000));
  EXPECT_EQ(tuner.current(), 2);
}

TEST(WorkerCountTuner, IgnoresFramesWithoutATime) {
  WorkerCountTuner tuner(2);
  for (int f = 0; f < 100; ++f) {
    EXPECT_EQ(tuner.frameEnded(0.0), 2);
    EXPECT_EQ(tuner.frameEnded(-1.0), 2);
    EXPECT_EQ(tuner.frameEnded(std::numeric_limits<double>::quiet_NaN()), 2);
  }
  WorkerCountTuner single(1);
  EXPECT_EQ(single.frameEnded(0.03), 1);
}

}  // namespace
}  // namespace omnipose::runtime
