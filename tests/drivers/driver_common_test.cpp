// What the camera drivers share (drivers/common), tested directly: the streaming policy of
// streaming.hpp (the drain-to-newest decision, the 32 -> 64 bit sequence numbers) and clock_offset.hpp (capture clock -> wall clock, a frame's capture
// time). The drivers' own tests (v4l2_test.cpp against the fake device) show the same
// behaviour end to end.

#include <gtest/gtest.h>

#include <cstdint>
#include <ctime>
#include <vector>

#include "common/clock_offset.hpp"
#include "common/streaming.hpp"

namespace omnipose::drivers {
namespace {

using namespace std::chrono_literals;

// ---- drain to the newest ------------------------------------------------------------------

TEST(PlanDrainTest, TheNewestGoodFrameIsDelivered) {
  auto all_good = [](std::size_t) { return true; };
  // 3 of 4 queued buffers completed: the newest (index 2) is delivered, 0 and 1 go back.
  DrainPlan p = planDrain(3, 4, 4, true, all_good);
  EXPECT_FALSE(p.ran_dry);
  EXPECT_EQ(p.deliver, 2);

  // The newest is flagged: the one before it.
  std::vector<bool> good = {true, true, false};
  p = planDrain(3, 4, 4, true, [&](std::size_t i) { return bool(good[i]); });
  EXPECT_EQ(p.deliver, 1);

  // None good: nothing delivered, and it is not "ran dry" (a bad-frame error).
  p = planDrain(2, 4, 4, true, [](std::size_t) { return false; });
  EXPECT_EQ(p.deliver, -1);
  EXPECT_FALSE(p.ran_dry);

  // Nothing completed (a spurious wake-up).
  p = planDrain(0, 4, 4, true, all_good);
  EXPECT_EQ(p.deliver, -1);
  EXPECT_FALSE(p.ran_dry);
}

TEST(PlanDrainTest, EveryBufferCompletedMeansRanDryAndEvenTheNewestIsStale) {
  auto all_good = [](std::size_t) { return true; };
  DrainPlan p = planDrain(4, 4, 4, /*drop_stale=*/true, all_good);
  EXPECT_TRUE(p.ran_dry);
  EXPECT_EQ(p.deliver, -1);

  // drop_stale off: the newest queued frame is delivered after all.
  p = planDrain(4, 4, 4, /*drop_stale=*/false, all_good);
  EXPECT_FALSE(p.ran_dry);
  EXPECT_EQ(p.deliver, 3);

  // Only 3 of the source's 4 buffers were queued when the driver looked, and all 3 came
  // back: not ran dry, which needs every buffer the source owns.
  p = planDrain(3, 3, 4, true, all_good);
  EXPECT_FALSE(p.ran_dry) << "the source owns 4 buffers, only 3 came back";
  EXPECT_EQ(p.deliver, 2);

  // A single buffer: every frame would be "stale"; it is delivered.
  p = planDrain(1, 1, 1, true, all_good);
  EXPECT_FALSE(p.ran_dry);
  EXPECT_EQ(p.deliver, 0);

  // Ran dry with flagged frames among them: still ran dry (all go back).
  p = planDrain(2, 2, 2, true, [](std::size_t i) { return i == 0; });
  EXPECT_TRUE(p.ran_dry);
}

// ---- sequence numbers ---------------------------------------------------------------------

TEST(SequenceTrackerTest, FirstFrameKeepsTheDriverNumberThenFollowsItsSteps) {
  SequenceTracker t;
  EXPECT_FALSE(t.started());
  EXPECT_EQ(t.delivered(7, 1'000'000, 30.0), 7u);
  EXPECT_TRUE(t.started());
  EXPECT_EQ(t.delivered(8, 1'033'333, 30.0), 8u);
  EXPECT_EQ(t.delivered(12, 1'166'667, 30.0), 12u) << "frames drained or lost are skipped";
  EXPECT_EQ(t.delivered(12, 1'166'667, 30.0), 12u) << "a repeated number stays";
}

TEST(SequenceTrackerTest, The32BitCounterWrapsInto64Bits) {
  SequenceTracker t;
  std::int64_t us = 0;
  EXPECT_EQ(t.delivered(0xFFFF'FFFEu, us += 33'333, 30.0), 0xFFFF'FFFEull);
  EXPECT_EQ(t.delivered(0xFFFF'FFFFu, us += 33'333, 30.0), 0xFFFF'FFFFull);
  EXPECT_EQ(t.delivered(0u, us += 33'333, 30.0), 0x1'0000'0000ull);
  EXPECT_EQ(t.delivered(3u, us += 100'000, 30.0), 0x1'0000'0003ull) << "a gap across the wrap";

  EXPECT_EQ(t.completed(0xFFFF'FFFFu), 0u) << "the first completed buffer: no loss known";
  EXPECT_EQ(t.completed(0u), 0u) << "the wrap is a step of one";
  EXPECT_EQ(t.completed(5u), 4u) << "1..4 dropped by the driver";
  EXPECT_EQ(t.completed(5u), 0u) << "a repeated number is no loss";
}

TEST(SequenceTrackerTest, AfterARestartTheGapIsTheElapsedTimeInFrames) {
  SequenceTracker t;
  EXPECT_EQ(t.delivered(99, 10'000'000, 30.0), 99u);
  EXPECT_EQ(t.delivered(100, 10'033'333, 30.0), 100u);
  EXPECT_EQ(t.completed(100), 0u);

  // Unplugged, back 3.1 s later; the driver's counter starts at 0 again.
  t.restart();
  EXPECT_EQ(t.completed(0), 0u) << "the new stream's first buffer is no gap";
  EXPECT_EQ(t.completed(1), 0u);
  EXPECT_EQ(t.delivered(1, 10'033'333 + 3'100'000, 30.0), 100u + 93u) << "round(3.1 s * 30)";
  EXPECT_EQ(t.delivered(2, 10'033'333 + 3'133'333, 30.0), 194u) << "then the driver's steps";

  // Frame rate unknown: one step.
  t.restart();
  EXPECT_EQ(t.delivered(0, 20'000'000, 0.0), 195u);
  // Capture time did not advance (a wall-clock step back): one step.
  t.restart();
  EXPECT_EQ(t.delivered(0, 19'000'000, 30.0), 196u);
  // Less than half a frame later: still at least one step.
  t.restart();
  EXPECT_EQ(t.delivered(0, 19'010'000, 30.0), 197u);
}

TEST(SequenceTrackerTest, RestartBeforeAnyFrameKeepsTheDriverNumber) {
  SequenceTracker t;
  t.restart();  // every stream start restarts, the first one too
  EXPECT_EQ(t.delivered(42, 5'000'000, 30.0), 42u);
  EXPECT_EQ(t.delivered(43, 5'033'333, 30.0), 43u);
}

// ---- clock offset (libcamera's SensorTimestamp is on CLOCK_BOOTTIME) ----------------------

TEST(ClockOffsetTest, SensorTimestampOnBoottimeBecomesWallClock) {
  // Synthetic: BOOTTIME 100 s, wall 1.7e9 s; one preempted sample must not win.
  const std::int64_t off = 1'700'000'000'000'000'000 - 100'000'000'000;
  const std::vector<ClockSample> samples = {
      {100'000'000'000, 100'000'050'000 + off, 100'000'100'000},  // 100 us bracket
      {100'000'200'000, 100'000'200'150 + off, 100'000'200'300},  // 300 ns bracket, exact
      {100'000'300'000, 100'000'300'900 + off, 100'000'301'000},  // 1 us, 400 ns skewed
  };
  const auto offset = offsetFromSamples(samples);
  ASSERT_TRUE(offset.valid);
  EXPECT_EQ(offset.offset_ns, off);
  EXPECT_EQ(offset.uncertainty_ns, 150);
  // A frame whose sensor started exposing at BOOTTIME 123.456789499 s.
  EXPECT_EQ(toWallMicroseconds(123'456'789'499, offset),
            (123'456'789'499 + off + 500) / 1000);
  EXPECT_EQ(toWallMicroseconds(123'456'789'499, offset) % 1'000'000, 456'789);
  EXPECT_EQ(toWallMicroseconds(123'456'789'500, offset) % 1'000'000, 456'790)
      << "rounded to the nearest microsecond";
}

TEST(ClockOffsetTest, BrokenSamplesAreIgnored) {
  const std::vector<ClockSample> samples = {{200, 5000, 100}};  // clock went back
  EXPECT_FALSE(offsetFromSamples(samples).valid);
  EXPECT_FALSE(offsetFromSamples({}).valid);
  EXPECT_EQ(toWallMicroseconds(-1500, ClockOffset{0, 0, true}), -1)
      << "rounds halves up also below zero";
}

TEST(ClockOffsetTest, RealBoottimeOffsetMatchesTheWallClock) {
  auto read = [](clockid_t c) {
    timespec ts{};
    ::clock_gettime(c, &ts);
    return toNanoseconds(ts);
  };
  const auto offset = measureClockOffset(read, CLOCK_BOOTTIME, 7);
  ASSERT_TRUE(offset.valid);
  EXPECT_LT(offset.uncertainty_ns, 1'000'000) << "a bracket of well under a millisecond";
  const std::int64_t boot_now = read(CLOCK_BOOTTIME);
  const std::int64_t wall_now_us = read(CLOCK_REALTIME) / 1000;
  EXPECT_NEAR(static_cast<double>(toWallMicroseconds(boot_now, offset)),
              static_cast<double>(wall_now_us), 2000.0);
}

// ---- capture time -------------------------------------------------------------------------

TEST(CaptureTimeTest, StampedFramesUseTheOffsetOthersTheWallClockNow) {
  const ClockOffset offset{1'000'000'000'000, 50, true};  // wall = capture + 1000 s
  int wall_reads = 0;
  auto wall = [&] {
    ++wall_reads;
    return std::int64_t{1'700'000'000'123'456'789};
  };
  EXPECT_EQ(captureTimeUs(2'000'000'499, offset, wall), 1'002'000'000);
  EXPECT_EQ(captureTimeUs(2'000'000'500, offset, wall), 1'002'000'001) << "rounded";
  EXPECT_EQ(wall_reads, 0) << "the wall clock is read only when needed";

  EXPECT_EQ(captureTimeUs(0, offset, wall), 1'700'000'000'123'457) << "not stamped";
  EXPECT_EQ(captureTimeUs(2'000'000'000, ClockOffset{}, wall), 1'700'000'000'123'457)
      << "no valid offset";
  EXPECT_EQ(wall_reads, 2);
}

}  // namespace
}  // namespace omnipose::drivers
