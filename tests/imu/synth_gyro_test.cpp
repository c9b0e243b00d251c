// The renderer's gyro (include/omnipose/synth/gyro.hpp) against the motion it renders: its
// rate is the derivative of the interpolated pose, and integrating its samples with the
// calibration it is written with gives back every frame pair's rotation; its noise, bias and
// bias walk have their stated statistics.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/gyro.hpp"
#include "omnipose/so3.hpp"
#include "omnipose/synth/gyro.hpp"
#include "omnipose/synth/motion.hpp"

namespace omnipose::synth {
namespace {

/// The mixed preset (up to 12 deg per frame about random axes) with track vibration: a
/// motion whose axis and rate change from frame to frame.
std::vector<StampedPose> shakyTrajectory() {
  MotionScript script = MotionScript::preset("mixed");
  script.frames = 20;
  script.vibration = Vibration{.amplitude_deg = 0.5, .min_hz = 1.0, .max_hz = 9.0, .seed = 3};
  return generateTrajectory(script);
}

/// The body rate of poseAtTime() by central differences of the pose.
Eigen::Vector3d numericRate(const std::vector<StampedPose>& trajectory, double t,
                            Interpolation interpolation) {
  const double h = 1e-6;
  const Eigen::Matrix3d R = poseAtTime(trajectory, t, interpolation).linear();
  const Eigen::Matrix3d dR = (poseAtTime(trajectory, t + h, interpolation).linear() -
                              poseAtTime(trajectory, t - h, interpolation).linear()) /
                             (2 * h);
  const Eigen::Matrix3d body = R.transpose() * dR;
  return {body(2, 1), body(0, 2), body(1, 0)};
}

TEST(SynthGyro, TheRateIsTheDerivativeOfTheRenderedMotion) {
  const auto trajectory = shakyTrajectory();
  for (const Interpolation interpolation : {Interpolation::kSmooth, Interpolation::kConstantVelocity}) {
    for (double t = -0.01; t < trajectory.back().timestamp + 0.01; t += 0.0037) {
      const Eigen::Vector3d exact = angularVelocityAtTime(trajectory, t, interpolation);
      EXPECT_LT((exact - numericRate(trajectory, t, interpolation)).norm(), 1e-6 * (1.0 + exact.norm()))
          << "t " << t;
    }
  }
  // Smooth: the same rate on either side of every frame, whose axis turns from frame to frame.
  for (std::size_t k = 1; k + 1 < trajectory.size(); ++k) {
    const double t = trajectory[k].timestamp;
    const Eigen::Vector3d before = angularVelocityAtTime(trajectory, t - 1e-9, Interpolation::kSmooth);
    const Eigen::Vector3d after = angularVelocityAtTime(trajectory, t + 1e-9, Interpolation::kSmooth);
    EXPECT_LT((after - before).norm(), 1e-6 * (1.0 + before.norm())) << "frame " << k;
  }
  EXPECT_TRUE(angularVelocityAtTime(std::vector<StampedPose>{{0.0, Eigen::Isometry3d::Identity()}}, 1.0,
                                    Interpolation::kSmooth)
                  .isZero());
}

TEST(SynthGyro, IntegratedWithItsCalibrationItGivesBackEveryFramePairsRotation) {
  const auto trajectory = shakyTrajectory();
  GyroSimulation gyro;
  gyro.rate_hz = 1000.0;
  gyro.noise_density = 0.0;
  gyro.bias = 0.0;
  gyro.time_offset_s = 0.0037;
  gyro.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(2.0, Eigen::Vector3d(1, -2, 0.5).normalized()));
  const double end = trajectory.back().timestamp;
  const GyroRecording recording = simulateGyro(trajectory, Interpolation::kSmooth, gyro, -0.05, end + 0.05);
  EXPECT_NEAR(recording.median_interval_s, 0.001, 1e-12);
  EXPECT_EQ(recording.gaps, 0);
  EXPECT_NEAR(recording.samples.front().t, -0.05 - 0.0037, 1e-12);
  EXPECT_LE(recording.samples.back().t + 0.0037, end + 0.05 + 1e-12);

  ImuCalibration exact{.rotation = gyro.rotation, .time_offset_s = gyro.time_offset_s, .gyro_noise_density = {}};
  ImuCalibration no_offset = exact;
  no_offset.time_offset_s = 0.0;
  ImuCalibration unrotated = exact;
  unrotated.rotation = Eigen::Quaterniond::Identity();
  double worst = 0.0, worst_no_offset = 0.0, worst_unrotated = 0.0;
  const Eigen::Vector3d zero = Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k + 1 < trajectory.size(); ++k) {
    // A frame pair, and an interval of a rolling shutter's rows (t_k + 5 ms .. t_k+1 + 20 ms).
    for (const auto& [t0, t1] : {std::pair(trajectory[k].timestamp, trajectory[k + 1].timestamp),
                                std::pair(trajectory[k].timestamp + 0.005, trajectory[k + 1].timestamp + 0.02)}) {
      const Eigen::Matrix3d truth = poseAtTime(trajectory, t0, Interpolation::kSmooth).linear().transpose() *
                                    poseAtTime(trajectory, t1, Interpolation::kSmooth).linear();
      const auto error = [&](const ImuCalibration& imu) {
        const auto R = integrateGyro(recording.samples, imu, zero, t0, t1, 0.01);
        EXPECT_TRUE(R.has_value());
        return R ? rotationVector(truth.transpose() * *R).norm() : 1.0;
      };
      worst = std::max(worst, error(exact));
      worst_no_offset = std::max(worst_no_offset, error(no_offset));
      worst_unrotated = std::max(worst_unrotated, error(unrotated));
    }
  }
  // 1 kHz. The rendered motion's acceleration changes at every frame (a cubic between the
  // frames' poses), so the integration is of second order here (the fourth on a smooth motion:
  // gyro_integration_test).
  EXPECT_LT(worst, 3e-5) << "rad";
  // The clock offset and the mounting matter, with the signs of their definitions.
  EXPECT_GT(worst_no_offset, 30 * worst) << worst_no_offset;
  EXPECT_GT(worst_unrotated, 0.01);
}

TEST(SynthGyro, TheSplineMovesWithContinuousVelocityAndAcceleration) {
  const auto trajectory = shakyTrajectory();
  const auto rate = [&](double t, Interpolation i) { return angularVelocityAtTime(trajectory, t, i); };
  // Its rate is the derivative of its pose.
  for (double t = 0.0; t < trajectory.back().timestamp; t += 0.0037) {
    const Eigen::Vector3d exact = rate(t, Interpolation::kSpline);
    EXPECT_LT((exact - numericRate(trajectory, t, Interpolation::kSpline)).norm(), 1e-6 * (1.0 + exact.norm()))
        << "t " << t;
  }
  // At every frame the rate and its derivative are the same on either side; the smooth
  // interpolation's derivative jumps there.
  const double e = 1e-5;
  double smooth_jump = 0.0;
  for (std::size_t k = 1; k + 1 < trajectory.size(); ++k) {
    const double t = trajectory[k].timestamp;
    for (const Interpolation i : {Interpolation::kSpline, Interpolation::kSmooth}) {
      const Eigen::Vector3d before = (rate(t - e, i) - rate(t - 2 * e, i)) / e;
      const Eigen::Vector3d after = (rate(t + 2 * e, i) - rate(t + e, i)) / e;
      const Eigen::Vector3d jerk_scale = (rate(t + 2 * e, i) - 2 * rate(t, i) + rate(t - 2 * e, i)) / (e * e);
      if (i == Interpolation::kSpline) {
        EXPECT_LT((after - before).norm(), 5 * e * (1.0 + jerk_scale.norm())) << "frame " << k;
        EXPECT_LT((rate(t + 1e-9, i) - rate(t - 1e-9, i)).norm(), 1e-6 * (1.0 + before.norm())) << "frame " << k;
      } else {
        smooth_jump = std::max(smooth_jump, (after - before).norm());
      }
    }
  }
  EXPECT_GT(smooth_jump, 10.0) << "rad/s^2";
  // A constant velocity is reproduced exactly; samples at uneven times are refused.
  std::vector<StampedPose> steady;
  for (int k = 0; k < 6; ++k) {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = rotationFromVector(Eigen::Vector3d(0.3, -0.1, 0.5) * k / 30.0);
    pose.translation() = Eigen::Vector3d(0.02, 0.0, -0.01) * k;
    steady.push_back({k / 30.0, pose});
  }
  for (double t = -0.01; t < 0.18; t += 0.013) {
    EXPECT_TRUE(poseAtTime(steady, t, Interpolation::kSpline).isApprox(poseAtTime(steady, t), 1e-12)) << t;
    EXPECT_TRUE(angularVelocityAtTime(steady, t, Interpolation::kSpline).isApprox(Eigen::Vector3d(0.3, -0.1, 0.5), 1e-12));
  }
  steady[3].timestamp += 0.001;
  EXPECT_THROW(poseAtTime(steady, 0.05, Interpolation::kSpline), std::invalid_argument);
}

// On the spline the integration converges at the third order (its jerk still changes at every
// frame), against the second on the smooth interpolation (whose acceleration does).
TEST(SynthGyro, OnTheSplineTheIntegratedGyroConvergesAtTheThirdOrder) {
  const auto trajectory = shakyTrajectory();
  std::vector<double> worst;
  for (const double rate_hz : {250.0, 500.0, 1000.0}) {
    GyroSimulation gyro;
    gyro.rate_hz = rate_hz;
    gyro.noise_density = 0.0;
    gyro.bias = 0.0;
    const GyroRecording r =
        simulateGyro(trajectory, Interpolation::kSpline, gyro, -0.05, trajectory.back().timestamp + 0.05);
    double w = 0.0;
    for (std::size_t k = 0; k + 1 < trajectory.size(); ++k) {
      const double t0 = trajectory[k].timestamp, t1 = trajectory[k + 1].timestamp;
      const Eigen::Matrix3d truth = poseAtTime(trajectory, t0, Interpolation::kSpline).linear().transpose() *
                                    poseAtTime(trajectory, t1, Interpolation::kSpline).linear();
      const auto R = integrateGyro(r.samples, ImuCalibration{}, Eigen::Vector3d::Zero(), t0, t1, 0.01);
      ASSERT_TRUE(R.has_value());
      w = std::max(w, rotationVector(truth.transpose() * *R).norm());
    }
    worst.push_back(w);
  }
  ::testing::Test::RecordProperty("worst_rad_250_500_1000_hz", std::to_string(worst[0]) + " " +
                                                                   std::to_string(worst[1]) + " " +
                                                                   std::to_string(worst[2]));
  EXPECT_LT(worst[0], 1e-4) << "rad per frame pair at 250 Hz";
  EXPECT_GT(worst[0] / worst[1], 6.0) << worst[0] << " " << worst[1];
  EXPECT_GT(worst[1] / worst[2], 6.0) << worst[1] << " " << worst[2];
}

TEST(SynthGyro, NoiseBiasAndBiasWalkHaveTheirStatistics) {
  // Standing still: every sample is bias + noise.
  const std::vector<StampedPose> still = {{0.0, Eigen::Isometry3d::Identity()},
                                          {1.0, Eigen::Isometry3d::Identity()}};
  GyroSimulation gyro;  // 200 Hz, 8.7e-5 rad/s/sqrt(Hz), bias 0.0087 rad/s
  gyro.seed = 11;
  const GyroRecording r = simulateGyro(still, Interpolation::kSmooth, gyro, 0.0, 200.0);
  ASSERT_EQ(r.samples.size(), 40001u);
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const GyroSample& s : r.samples) mean += s.rate;
  mean /= static_cast<double>(r.samples.size());
  Eigen::Vector3d variance = Eigen::Vector3d::Zero();
  for (const GyroSample& s : r.samples) variance += (s.rate - mean).cwiseAbs2();
  variance /= static_cast<double>(r.samples.size() - 1);
  const double sigma = gyro.noise_density * std::sqrt(gyro.rate_hz);
  EXPECT_NEAR(mean.norm(), gyro.bias, 4 * sigma / std::sqrt(40001.0) * std::sqrt(3.0));
  for (int axis = 0; axis < 3; ++axis)
    EXPECT_NEAR(std::sqrt(variance[axis]), sigma, 0.02 * sigma) << "axis " << axis;
  // Another seed: another bias direction (the mean of a second's samples is the bias within
  // sigma / sqrt(200) per axis), the same length.
  gyro.seed = 12;
  const GyroRecording other = simulateGyro(still, Interpolation::kSmooth, gyro, 0.0, 1.0);
  Eigen::Vector3d other_mean = Eigen::Vector3d::Zero();
  for (const GyroSample& s : other.samples) other_mean += s.rate;
  other_mean /= static_cast<double>(other.samples.size());
  EXPECT_NEAR(other_mean.norm(), gyro.bias, 6 * sigma / std::sqrt(200.0));
  EXPECT_GT((other_mean - mean).norm(), 0.2 * gyro.bias);

  // Without white noise the differences of consecutive samples are the bias walk's steps.
  gyro.noise_density = 0.0;
  gyro.bias_random_walk = 1e-3;
  const GyroRecording walk = simulateGyro(still, Interpolation::kSmooth, gyro, 0.0, 100.0);
  double sum2 = 0.0;
  for (std::size_t i = 1; i < walk.samples.size(); ++i)
    sum2 += (walk.samples[i].rate - walk.samples[i - 1].rate).squaredNorm();
  const double step_std = std::sqrt(sum2 / (3.0 * static_cast<double>(walk.samples.size() - 1)));
  EXPECT_NEAR(step_std, gyro.bias_random_walk * std::sqrt(1.0 / gyro.rate_hz),
              0.02 * gyro.bias_random_walk * std::sqrt(1.0 / gyro.rate_hz));
  EXPECT_NEAR(walk.samples.front().rate.norm(), gyro.bias, 1e-15);
}

TEST(SynthGyro, InvalidSettingsAreRefusedNamingTheField) {
  GyroSimulation bad;
  bad.rate_hz = 0.0;
  bad.noise_density = -1.0;
  bad.bias = std::nan("");
  bad.bias_random_walk = -1e-3;
  bad.time_offset_s = 2.0;
  bad.rotation = Eigen::Quaterniond(1.0, 0.1, 0.0, 0.0);
  const auto problems = bad.validate();
  ASSERT_EQ(problems.size(), 6u);
  for (const char* field : {"gyro.rate_hz", "gyro.noise_density", "gyro.bias", "gyro.bias_random_walk",
                            "gyro.time_offset_s", "gyro.rotation"}) {
    EXPECT_TRUE(std::any_of(problems.begin(), problems.end(),
                            [&](const std::string& p) { return p.rfind(std::string(field) + ":", 0) == 0; }))
        << field;
  }
  EXPECT_TRUE(GyroSimulation{}.validate().empty());
  const std::vector<StampedPose> one = {{0.0, Eigen::Isometry3d::Identity()}};
  EXPECT_THROW(simulateGyro(one, Interpolation::kSmooth, bad, 0.0, 1.0), std::invalid_argument);
  EXPECT_THROW(simulateGyro(one, Interpolation::kSmooth, GyroSimulation{}, 1.0, 0.0), std::invalid_argument);
  EXPECT_THROW(simulateGyro({}, Interpolation::kSmooth, GyroSimulation{}, 0.0, 1.0), std::invalid_argument);
}

}  // namespace
}  // namespace omnipose::synth
