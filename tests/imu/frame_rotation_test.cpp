// The camera's rotation within a frame from the gyro (src/pipeline/frame_rotation.hpp),
// against integrateGyro() at any capture time, and its refusals.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/so3.hpp"
#include "pipeline/frame_rotation.hpp"

namespace omnipose::pipeline {
namespace {

/// A 400 Hz gyro on a camera whose rate turns smoothly (a shaking roll and a changing yaw),
/// in the IMU's axes (mounted 30 degrees off about x), on the IMU's clock.
struct Recording {
  ImuCalibration imu;
  std::vector<GyroSample> samples;
};

Eigen::Vector3d cameraRate(double t) {
  return {0.4 * std::sin(2.0 * 3.14159 * 7.0 * t), 0.1 * std::cos(3.0 * t), 1.2 + 0.8 * t};
}

Recording recording(double from, double to) {
  Recording r;
  r.imu.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.5236, Eigen::Vector3d::UnitX()));
  r.imu.time_offset_s = 0.004;
  const Eigen::Matrix3d imu_from_camera = r.imu.rotation.toRotationMatrix().transpose();
  for (double t = from; t <= to; t += 0.0025)
    r.samples.push_back({t, imu_from_camera * cameraRate(t + r.imu.time_offset_s)});
  return r;
}

TEST(FrameRotation, FollowsTheGyroAtEveryCaptureTime) {
  const Recording r = recording(0.0, 0.2);
  const double readout = 0.0267, time = 0.1, gap = 0.02;
  FrameRotation rotation(readout);
  ASSERT_TRUE(rotation.measure(r.samples, r.imu, Eigen::Vector3d::Zero(), time, gap, 0.0));
  ASSERT_TRUE(rotation.known());
  for (double s = 0.0; s <= readout; s += 0.0013) {
    const auto exact = integrateGyro(r.samples, r.imu, Eigen::Vector3d::Zero(), time, time + s, gap);
    ASSERT_TRUE(exact.has_value());
    EXPECT_LT((rotation.turnAt(s) - rotationVector(*exact)).norm(), 2e-7) << "s = " << s;
  }
  // Beyond the span: on along the end's rate.
  const Eigen::Vector3d end = rotation.turnAt(readout);
  EXPECT_LT((rotation.turnAt(readout + 0.001) - end).norm(), 0.0016);
  EXPECT_EQ(rotation.turnAt(0.0), Eigen::Vector3d::Zero());
}

TEST(FrameRotation, AnExposedRowShowsTheMeanTurnOverItsExposure) {
  const Recording r = recording(0.0, 0.2);
  const double readout = 0.0267, exposure = 0.01, time = 0.1, gap = 0.02;
  FrameRotation rotation(readout, exposure);
  ASSERT_TRUE(rotation.measure(r.samples, r.imu, Eigen::Vector3d::Zero(), time, gap, exposure));
  // Still the turn from the timestamp, now also over the exposure's margins (within twice
  // the curve's error: the timestamp falls between two kept samples now).
  for (double s = -0.5 * exposure; s <= readout + 0.5 * exposure; s += 0.0013) {
    const auto exact =
        integrateGyro(r.samples, r.imu, Eigen::Vector3d::Zero(), time, time + s, gap);
    ASSERT_TRUE(exact.has_value());
    EXPECT_LT((rotation.turnAt(s) - rotationVector(*exact)).norm(), 4e-7) << "s = " << s;
  }
  // The mean over the exposure, against 2001 turns integrated on their own.
  for (const double s : {0.0, 0.0071, 0.5 * readout, readout}) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    constexpr int kPoints = 2001;
    for (int i = 0; i < kPoints; ++i) {
      const double at = s + exposure * ((i + 0.5) / kPoints - 0.5);
      mean += rotationVector(
          *integrateGyro(r.samples, r.imu, Eigen::Vector3d::Zero(), time, time + at, gap));
    }
    mean /= kPoints;
    EXPECT_LT((rotation.exposedTurnAt(s) - mean).norm(), 4e-7) << "s = " << s;
    // It differs from the turn at the capture time by the rate's change over the exposure
    // (exposure^2 / 24 times the angular acceleration, here about 1e-5 rad).
    EXPECT_GT((rotation.exposedTurnAt(s) - rotation.turnAt(s)).norm(), 3e-6) << "s = " << s;
  }
  // Without an exposure it is the turn at the capture time, bit for bit.
  FrameRotation instant(readout);
  ASSERT_TRUE(instant.measure(r.samples, r.imu, Eigen::Vector3d::Zero(), time, gap, 0.0));
  EXPECT_EQ(instant.exposedTurnAt(0.011), instant.turnAt(0.011));
  // The exposure's margins need samples too: these end 1.5-4 ms after the last row's capture.
  const Recording short_r = recording(0.0, time + readout + 0.004 - r.imu.time_offset_s);
  EXPECT_TRUE(instant.measure(short_r.samples, r.imu, Eigen::Vector3d::Zero(), time, gap, 0.0));
  EXPECT_FALSE(
      rotation.measure(short_r.samples, r.imu, Eigen::Vector3d::Zero(), time, gap, exposure));
}

TEST(FrameRotation, AFrameStatingItsOwnExposureIsMeasuredOverIt) {
  const Recording r = recording(0.0, 0.3);
  const double readout = 0.0267, time = 0.1, gap = 0.02;
  // Room for exposures up to 30 ms.
  FrameRotation varying(readout, 0.03);
  EXPECT_EQ(varying.maxExposure(), 0.03);
  for (const double exposure : {0.004, 0.03, 0.0, 0.017}) {
    FrameRotation fixed(readout, exposure);
    ASSERT_TRUE(fixed.measure(r.samples, r.imu, Eigen::Vector3d::Zero(), time, gap, exposure));
    ASSERT_TRUE(varying.measure(r.samples, r.imu, Eigen::Vector3d::Zero(), time, gap, exposure));
    EXPECT_EQ(varying.exposure(), exposure);
    // Bit for bit what a rotation made for that exposure measures.
    for (const double s : {-0.011, 0.0, 0.0071, readout, readout + 0.012}) {
      EXPECT_EQ(varying.turnAt(s), fixed.turnAt(s)) << exposure << " s = " << s;
      EXPECT_EQ(varying.exposedTurnAt(s), fixed.exposedTurnAt(s)) << exposure << " s = " << s;
    }
    // A copy carries the frame's exposure (a previous or keyframe's rows).
    FrameRotation copy(readout, 0.03);
    copy = varying;
    EXPECT_EQ(copy.exposedTurnAt(0.0071), fixed.exposedTurnAt(0.0071));
  }
  // Longer than its room, negative or not a number: nothing measured.
  for (const double bad : {0.031, -0.001, std::numeric_limits<double>::quiet_NaN()}) {
    EXPECT_FALSE(varying.measure(r.samples, r.imu, Eigen::Vector3d::Zero(), time, gap, bad));
    EXPECT_FALSE(varying.known());
  }
}

TEST(FrameRotation, IsUnknownWhereTheSamplesDoNotReach) {
  const Recording r = recording(0.0, 0.1);
  FrameRotation rotation(0.03);
  // The samples end 10 ms into the readout (camera time 0.104).
  EXPECT_FALSE(rotation.measure(r.samples, r.imu, Eigen::Vector3d::Zero(), 0.094, 0.02, 0.0));
  EXPECT_FALSE(rotation.known());
  ASSERT_TRUE(rotation.measure(r.samples, r.imu, Eigen::Vector3d::Zero(), 0.05, 0.02, 0.0));
  // A gap longer than the largest interval allowed.
  std::vector<GyroSample> holed;
  for (const GyroSample& s : r.samples)
    if (s.t < 0.055 || s.t > 0.07) holed.push_back(s);
  EXPECT_FALSE(rotation.measure(holed, r.imu, Eigen::Vector3d::Zero(), 0.05, 0.01, 0.0));
  EXPECT_FALSE(rotation.known());
}

}  // namespace
}  // namespace omnipose::pipeline
