// The camera's rotation integrated from gyro samples (include/omnipose/gyro.hpp), against
// rotations known in closed form: a constant rate, a bias, the mounting and the clock offset.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/gyro.hpp"
#include "omnipose/so3.hpp"

namespace omnipose {
namespace {

/// Samples of a constant rate `rate` (IMU axes) every `interval` seconds from t = begin.
std::vector<GyroSample> constantRate(const Eigen::Vector3d& rate, double begin, double interval,
                                     int count) {
  std::vector<GyroSample> samples;
  for (int i = 0; i < count; ++i) samples.push_back({begin + i * interval, rate});
  return samples;
}

double angleBetween(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return rotationVector(a.transpose() * b).norm();
}

TEST(IntegrateGyro, AConstantRateTurnsByRateTimesDuration) {
  const Eigen::Vector3d w(0.3, -0.2, 1.1);  // rad/s
  const auto samples = constantRate(w, 10.0, 0.005, 400);
  const auto R = integrateGyro(samples, ImuCalibration{}, Eigen::Vector3d::Zero(), 10.0123, 10.3456, 0.1);
  ASSERT_TRUE(R.has_value());
  EXPECT_LT(angleBetween(*R, rotationFromVector(w * (10.3456 - 10.0123))), 1e-12);
  // Backwards: the inverse rotation; a zero-length interval: the identity.
  const auto back = integrateGyro(samples, ImuCalibration{}, Eigen::Vector3d::Zero(), 10.3456, 10.0123, 0.1);
  ASSERT_TRUE(back.has_value());
  EXPECT_LT(angleBetween(*back, R->transpose()), 1e-12);
  const auto none = integrateGyro(samples, ImuCalibration{}, Eigen::Vector3d::Zero(), 10.2, 10.2, 0.1);
  ASSERT_TRUE(none.has_value());
  EXPECT_TRUE(none->isIdentity(1e-15));
}

TEST(IntegrateGyro, RemovesTheBiasInTheImuAxesAndTurnsTheRatesIntoTheCamerasAxes) {
  // The IMU is mounted turned 90 deg about the camera's z: its x is the camera's y. A rate
  // about the IMU's x is a rate about the camera's y.
  ImuCalibration imu;
  imu.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()));
  const Eigen::Vector3d bias(0.01, 0.02, -0.03);
  const auto samples = constantRate(Eigen::Vector3d(0.5, 0.0, 0.0) + bias, 0.0, 0.01, 101);
  const auto R = integrateGyro(samples, imu, bias, 0.0, 1.0, 0.05);
  ASSERT_TRUE(R.has_value());
  EXPECT_LT(angleBetween(*R, rotationFromVector(Eigen::Vector3d(0.0, 0.5, 0.0))), 1e-12);
}

TEST(IntegrateGyro, ALinearRateIsIntegratedExactlyAboutAFixedAxis) {
  // w(t) = (a + b t) along one axis: the angle is a t + b t^2 / 2 between any two instants,
  // however they fall between the samples.
  const Eigen::Vector3d axis = Eigen::Vector3d(1, 2, -2).normalized();
  std::vector<GyroSample> samples;
  for (int i = 0; i <= 100; ++i) {
    const double t = 0.01 * i;
    samples.push_back({t, (0.2 + 1.5 * t) * axis});
  }
  const auto angle = [](double t) { return 0.2 * t + 0.75 * t * t; };
  const auto R = integrateGyro(samples, ImuCalibration{}, Eigen::Vector3d::Zero(), 0.1234, 0.8765, 0.05);
  ASSERT_TRUE(R.has_value());
  EXPECT_LT(angleBetween(*R, rotationFromVector((angle(0.8765) - angle(0.1234)) * axis)), 1e-12);
}

TEST(IntegrateGyro, ASampleStampedTIsTakenAtCameraTimeTPlusTheOffset) {
  // The rate is 1 rad/s about z from IMU time 1.0 on, 0 before. With time_offset_s = 0.25
  // that step is at camera time 1.25: over camera [1.0, 2.0] the camera turns 0.75 rad.
  std::vector<GyroSample> samples;
  for (int i = 0; i <= 300; ++i) {
    const double t = 0.01 * i;
    samples.push_back({t, Eigen::Vector3d(0, 0, t >= 1.0 ? 1.0 : 0.0)});
  }
  ImuCalibration imu;
  imu.time_offset_s = 0.25;
  const auto R = integrateGyro(samples, imu, Eigen::Vector3d::Zero(), 1.0, 2.0, 0.05);
  ASSERT_TRUE(R.has_value());
  // Between samples the rate is the cubic through the four around them: over [0.98, 0.99],
  // [0.99, 1.0] and [1.0, 1.01] the camera turns -1/24, 12/24 and 25/24 of 0.01 rad, so the
  // step shows as 0.005 rad turned before IMU time 1.0.
  EXPECT_NEAR(rotationVector(*R).z(), 0.755, 1e-12);
}

TEST(IntegrateGyro, IsFourthOrderOnASmoothMotionAboutATurningAxis) {
  // R(t) = exp([phi(t)]x) with a smooth phi: the body rate is rightJacobian(phi) phi'. Each
  // halving of the sampling interval divides the error by about 16.
  const auto phi = [](double t) { return Eigen::Vector3d(0.8 * std::sin(3 * t), t * t - 0.5 * t, 0.6 * std::cos(5 * t)); };
  const auto dphi = [](double t) { return Eigen::Vector3d(2.4 * std::cos(3 * t), 2 * t - 0.5, -3.0 * std::sin(5 * t)); };
  const double t0 = 0.1234, t1 = 0.4567;
  const Eigen::Matrix3d truth = rotationFromVector(phi(t0)).transpose() * rotationFromVector(phi(t1));
  std::vector<double> errors;
  for (const double rate_hz : {200.0, 400.0, 800.0}) {
    std::vector<GyroSample> samples;
    for (double t = 0.0; t < 0.6; t += 1.0 / rate_hz) samples.push_back({t, rightJacobian(phi(t)) * dphi(t)});
    const auto R = integrateGyro(samples, ImuCalibration{}, Eigen::Vector3d::Zero(), t0, t1, 0.1);
    ASSERT_TRUE(R.has_value());
    errors.push_back(angleBetween(*R, truth));
  }
  EXPECT_LT(errors[0], 1e-6) << "rad at 200 Hz";
  EXPECT_GT(errors[0] / errors[1], 12.0) << errors[0] << " " << errors[1];
  EXPECT_GT(errors[1] / errors[2], 12.0) << errors[1] << " " << errors[2];
}

TEST(IntegrateGyro, AnIntervalTheSamplesDoNotCoverOrThatHasAGapIsRefused) {
  const auto samples = constantRate(Eigen::Vector3d(0, 0, 1), 1.0, 0.01, 101);  // 1.0 .. 2.0 s
  const ImuCalibration imu;
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  EXPECT_TRUE(integrateGyro(samples, imu, zero, 1.0, 2.0, 0.05).has_value());  // exactly covered
  EXPECT_FALSE(integrateGyro(samples, imu, zero, 0.999, 1.5, 0.05).has_value());
  EXPECT_FALSE(integrateGyro(samples, imu, zero, 1.5, 2.001, 0.05).has_value());
  EXPECT_FALSE(integrateGyro(samples, imu, zero, 2.001, 1.5, 0.05).has_value());
  EXPECT_FALSE(integrateGyro({}, imu, zero, 1.5, 1.6, 0.05).has_value());
  EXPECT_FALSE(integrateGyro(std::span(samples).first(1), imu, zero, 1.0, 1.0, 0.05).has_value());
  // Samples 1.30 .. 1.60 missing: a gap of 0.4 s, refused only where the interval meets it.
  std::vector<GyroSample> gappy;
  for (const GyroSample& s : samples)
    if (s.t < 1.295 || s.t > 1.605) gappy.push_back(s);
  EXPECT_FALSE(integrateGyro(gappy, imu, zero, 1.2, 1.7, 0.05).has_value());
  EXPECT_FALSE(integrateGyro(gappy, imu, zero, 1.35, 1.4, 0.05).has_value());
  EXPECT_TRUE(integrateGyro(gappy, imu, zero, 1.0, 1.28, 0.05).has_value());
  EXPECT_TRUE(integrateGyro(gappy, imu, zero, 1.62, 2.0, 0.05).has_value());
  EXPECT_TRUE(integrateGyro(gappy, imu, zero, 1.2, 1.7, 0.5).has_value());  // a longer gap allowed
  // A sample beyond a gap does not bend the rate before it: up to the gap the camera turns
  // at the rate of the samples there, however different the one after the gap.
  std::vector<GyroSample> jump = constantRate(Eigen::Vector3d(0, 0, 1), 0.0, 0.01, 101);  // 0 .. 1 s
  jump.push_back({2.0, Eigen::Vector3d(50, -50, 50)});
  const auto R = integrateGyro(jump, imu, zero, 0.5, 1.0, 0.05);
  ASSERT_TRUE(R.has_value());
  EXPECT_LT(angleBetween(*R, rotationFromVector(Eigen::Vector3d(0, 0, 0.5))), 1e-12);
}

// A recording given as it would have arrived: the samples stamped up to 10 ms after the
// frame's last row, on the camera's clock (a sample stamped t is taken at t + offset).
TEST(GyroSamplesArrivedBy, CountsTheSamplesStreamedByTheEndOfTheFramesReadout) {
  const auto samples = constantRate(Eigen::Vector3d(0, 0, 1), 0.0, 0.01, 101);  // 0 .. 1 s
  ImuCalibration imu;
  EXPECT_EQ(gyroSamplesArrivedBy(samples, imu, 0.0, 0.505), 52u);    // up to 0.515 s
  EXPECT_EQ(gyroSamplesArrivedBy(samples, imu, 0.03, 0.505), 55u);   // up to 0.545 s
  EXPECT_EQ(gyroSamplesArrivedBy(samples, imu, -0.03, 0.505), 55u);  // last row first: the same
  imu.time_offset_s = 0.1;  // the IMU's clock 0.1 s behind: camera time 0.515 s is stamp 0.415 s
  EXPECT_EQ(gyroSamplesArrivedBy(samples, imu, 0.0, 0.505), 42u);
  EXPECT_EQ(gyroSamplesArrivedBy(samples, imu, 0.0, -1.0), 0u);
  EXPECT_EQ(gyroSamplesArrivedBy(samples, imu, 0.0, 5.0), 101u);
  EXPECT_EQ(gyroSamplesArrivedBy({}, imu, 0.0, 0.5), 0u);
  // In the order received: counting stops at the first sample stamped too late.
  std::vector<GyroSample> unordered = {{0.1, {}}, {0.9, {}}, {0.2, {}}};
  EXPECT_EQ(gyroSamplesArrivedBy(unordered, ImuCalibration{}, 0.0, 0.5), 1u);
}

}  // namespace
}  // namespace omnipose
