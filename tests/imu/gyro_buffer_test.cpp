// The live gyro stream's buffer (src/imu/gyro_buffer.hpp): what it refuses, a clock that
// starts over, and a full buffer.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "imu/gyro_buffer.hpp"

namespace omnipose::imu {
namespace {

GyroSample at(double t, double rate = 0.1) { return {t, Eigen::Vector3d(rate, -rate, 0.5 * rate)}; }

TEST(GyroBuffer, KeepsSamplesInStrictlyIncreasingTime) {
  GyroBuffer buffer(64);
  EXPECT_EQ(buffer.push(at(1.000)), GyroIntake::kAccepted);
  EXPECT_EQ(buffer.push(at(1.005)), GyroIntake::kAccepted);
  EXPECT_EQ(buffer.push(at(1.005)), GyroIntake::kOutOfOrder);  // given twice
  EXPECT_EQ(buffer.push(at(1.002)), GyroIntake::kOutOfOrder);  // late
  EXPECT_EQ(buffer.push(at(1.010)), GyroIntake::kAccepted);
  ASSERT_EQ(buffer.samples().size(), 3u);
  EXPECT_DOUBLE_EQ(buffer.samples().back().t, 1.010);
}

TEST(GyroBuffer, RefusesSamplesThatAreNotMeasurements) {
  GyroBuffer buffer(64);
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(buffer.push({nan, Eigen::Vector3d::Zero()}), GyroIntake::kNotFinite);
  EXPECT_EQ(buffer.push({0.0, Eigen::Vector3d(0.0, inf, 0.0)}), GyroIntake::kNotFinite);
  EXPECT_EQ(buffer.push({0.0, Eigen::Vector3d(0.0, 0.0, nan)}), GyroIntake::kNotFinite);
  EXPECT_EQ(buffer.push(at(0.0, kMaxGyroRate * 1.01)), GyroIntake::kTooFast);
  EXPECT_EQ(buffer.push(at(0.0, -kMaxGyroRate)), GyroIntake::kAccepted);  // the limit itself
  EXPECT_EQ(buffer.samples().size(), 1u);
}

TEST(GyroBuffer, AClockThatJumpsBackStartsTheBufferOver) {
  GyroBuffer buffer(64);
  for (int i = 0; i < 10; ++i) ASSERT_EQ(buffer.push(at(100.0 + 0.005 * i)), GyroIntake::kAccepted);
  // Within kClockJumpS back: a late sample; beyond: the clock started over.
  EXPECT_EQ(buffer.push(at(100.0 - 0.9 * GyroBuffer::kClockJumpS)), GyroIntake::kOutOfOrder);
  EXPECT_EQ(buffer.push(at(0.5)), GyroIntake::kClockRestart);
  ASSERT_EQ(buffer.samples().size(), 1u);
  EXPECT_EQ(buffer.push(at(0.505)), GyroIntake::kAccepted);
  EXPECT_EQ(buffer.samples().size(), 2u);
}

TEST(GyroBuffer, AFullBufferDropsItsOldestHalfAndKeepsTheNewest) {
  GyroBuffer buffer(64);
  for (int i = 0; i < 64; ++i) ASSERT_EQ(buffer.push(at(0.001 * i)), GyroIntake::kAccepted);
  EXPECT_EQ(buffer.samples().size(), 64u);
  ASSERT_EQ(buffer.push(at(0.064)), GyroIntake::kAccepted);
  ASSERT_EQ(buffer.samples().size(), 33u);
  EXPECT_DOUBLE_EQ(buffer.samples().front().t, 0.032);
  EXPECT_DOUBLE_EQ(buffer.samples().back().t, 0.064);
  for (std::size_t i = 1; i < buffer.samples().size(); ++i)
    EXPECT_GT(buffer.samples()[i].t, buffer.samples()[i - 1].t);
}

TEST(GyroBuffer, TheTypicalIntervalIsTheMedianOfTheRecentOnes) {
  GyroBuffer buffer(64);
  EXPECT_EQ(buffer.typicalInterval(), 0.0);
  buffer.push(at(0.0));
  EXPECT_EQ(buffer.typicalInterval(), 0.0);
  double t = 0.0;
  for (int i = 0; i < 20; ++i) buffer.push(at(t += 0.005));
  buffer.push(at(t += 0.2));  // one gap does not move the median
  EXPECT_NEAR(buffer.typicalInterval(), 0.005, 1e-12);
}

}  // namespace
}  // namespace omnipose::imu
