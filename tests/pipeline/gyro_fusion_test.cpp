// The images' motion combined with the gyro's rotation (src/pipeline/gyro_fusion.hpp,
// private): the Gaussian update it is, checked on hand-made covariances, and against the
// exact renderer: people crossing in front of a driving robot bend the images' yaw, not the
// combined one (PipelineOptions::gyro_fusion).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <random>
#include <numbers>
#include <sstream>
#include <vector>

#include "omnipose/odometry.hpp"
#include "omnipose/so3.hpp"
#include "omnipose/synth/gyro.hpp"
#include "omnipose/synth/synth.hpp"
#include "pipeline/gyro_bias.hpp"
#include "pipeline/gyro_fusion.hpp"
#include "render_fixture.hpp"
#include "test_figures.hpp"

namespace omnipose {
namespace {

using pipeline::fuseGyroRotation;
using pipeline::gyroRotationVariance;

/// An estimate whose rotation has variance `v` per axis and whose translation's x is
/// correlated with the yaw by `c` (covariance), tau's own variance 1e-4.
MotionEstimate estimateWith(double v, double c) {
  MotionEstimate e;
  e.covariance.setZero();
  e.covariance.topLeftCorner<3, 3>().diagonal().setConstant(v);
  e.covariance.bottomRightCorner<3, 3>().diagonal().setConstant(1e-4);
  e.covariance(2, 3) = e.covariance(3, 2) = c;
  e.tau = Eigen::Vector3d(0.01, 0.0, 0.0);
  e.status = FitStatus::kOk;
  return e;
}

TEST(GyroFusion, AnExactGyroGivesItsRotation) {
  Eigen::Matrix3d R = rotationFromVector(Eigen::Vector3d(0.001, -0.002, 0.05));
  const Eigen::Matrix3d G = rotationFromVector(Eigen::Vector3d(0.0012, -0.0021, 0.0493));
  MotionEstimate e = estimateWith(1e-6, 0.0);
  ASSERT_TRUE(fuseGyroRotation(R, e, G, 1e-16));
  EXPECT_LT(rotationVector(R.transpose() * G).norm(), 1e-9);
  EXPECT_LT((e.omega - rotationVector(G)).norm(), 1e-9);
  EXPECT_LT((e.covariance.topLeftCorner<3, 3>()).norm(), 1e-14);
}

TEST(GyroFusion, EqualVariancesMeetHalfWay) {
  const Eigen::Vector3d images(0.0, 0.0, 0.0300), gyro(0.0, 0.0, 0.0310);
  Eigen::Matrix3d R = rotationFromVector(images);
  MotionEstimate e = estimateWith(4e-8, 0.0);
  ASSERT_TRUE(fuseGyroRotation(R, e, rotationFromVector(gyro), 4e-8));
  EXPECT_NEAR(rotationVector(R).z(), 0.0305, 1e-9);
  EXPECT_NEAR(e.covariance(2, 2), 2e-8, 1e-15);  // the variance halved
  EXPECT_NEAR(e.covariance(0, 0), 2e-8, 1e-15);
  EXPECT_NEAR(e.tau.x(), 0.01, 1e-15);  // uncorrelated: the translation stays
}

TEST(GyroFusion, TheTranslationFollowsThroughItsCorrelationWithTheYaw) {
  // yaw variance 1e-6, tau_x correlated by 5e-6: a yaw 1 mrad too large comes with tau_x
  // 5e-3 too large on average; the gyro (exact) says the yaw is 1 mrad smaller.
  Eigen::Matrix3d R = rotationFromVector(Eigen::Vector3d(0.0, 0.0, 0.011));
  MotionEstimate e = estimateWith(1e-6, 5e-6);
  ASSERT_TRUE(fuseGyroRotation(R, e, rotationFromVector(Eigen::Vector3d(0.0, 0.0, 0.010)),
                               1e-16));
  EXPECT_NEAR(rotationVector(R).z(), 0.010, 1e-9);
  EXPECT_NEAR(e.tau.x(), 0.01 - 5e-3, 1e-8);
  // tau_x's variance loses what the yaw explained: 1e-4 - (5e-6)^2 / 1e-6.
  EXPECT_NEAR(e.covariance(3, 3), 1e-4 - 2.5e-5, 1e-12);
  EXPECT_TRUE(e.covariance.isApprox(e.covariance.transpose()));
}

TEST(GyroFusion, NothingChangesWithoutAUsableVariance) {
  const Eigen::Matrix3d R0 = rotationFromVector(Eigen::Vector3d(0.0, 0.0, 0.02));
  const Eigen::Matrix3d G = rotationFromVector(Eigen::Vector3d(0.0, 0.0, 0.03));
  for (const double q : {0.0, -1.0, std::numeric_limits<double>::infinity(),
                         std::numeric_limits<double>::quiet_NaN()}) {
    Eigen::Matrix3d R = R0;
    MotionEstimate e = estimateWith(1e-6, 0.0);
    EXPECT_FALSE(fuseGyroRotation(R, e, G, q)) << q;
    EXPECT_EQ(R, R0);
    EXPECT_EQ(e.tau, estimateWith(1e-6, 0.0).tau);
  }
  Eigen::Matrix3d R = R0;
  MotionEstimate lost = estimateWith(0.0, 0.0);  // a fit that gave no covariance
  EXPECT_FALSE(fuseGyroRotation(R, lost, G, 1e-8));
  EXPECT_EQ(R, R0);
}

TEST(GyroFusion, TheGyrosVarianceGrowsWithTheIntervalAndTheBiasUncertainty) {
  EXPECT_DOUBLE_EQ(gyroRotationVariance(1e-4, 0.0, 0.04), 1e-8 * 0.04);
  EXPECT_DOUBLE_EQ(gyroRotationVariance(0.0, 1e-3, 0.5), 0.25e-6);
  const double unknown = std::numeric_limits<double>::infinity();
  EXPECT_TRUE(std::isinf(gyroRotationVariance(1e-4, unknown, 0.03)));
}

constexpr double kBiasDt = 1.0 / 30.0;  ///< the pairs' interval in the GyroBias tests, s

/// Gives `bias` the reading `reading` (rad/s): a pair of kBiasDt whose images turned by
/// -(reading - estimate) dt more than the gyro with its estimate removed (gyro identity, C
/// identity), its rotation's sigma `sigma` rad/s per axis times the interval.
bool giveReading(pipeline::GyroBias& bias, const Eigen::Vector3d& reading, double sigma,
                 bool translating = false) {
  const Eigen::Vector3d error = reading - bias.bias();
  const double variance = std::pow(sigma * kBiasDt, 2);
  return bias.update({.images = rotationFromVector(-error * kBiasDt),
                      .images_covariance = Eigen::Matrix3d::Identity() * variance,
                      .dt = kBiasDt,
                      .translating = translating},
                     Eigen::Matrix3d::Identity());
}

// The gyro's bias as the images read it (src/pipeline/gyro_bias.hpp), pairs that people bent
// among the readings.
TEST(GyroBias, PairsThatPeopleBentDoNotMoveIt) {
  const Eigen::Vector3d truth(0.008, -0.004, 0.002);  // rad/s
  constexpr double kSigma = 0.002;                    // 0.07 mrad a pair
  std::mt19937 rng(3);
  std::normal_distribution<double> noise(0.0, kSigma);
  pipeline::GyroBias bias;
  const auto give = [&](const Eigen::Vector3d& reading) {
    return giveReading(bias, reading, kSigma);
  };
  const auto clean = [&] {
    const double x = noise(rng), y = noise(rng), z = noise(rng);
    return Eigen::Vector3d(truth + Eigen::Vector3d(x, y, z));
  };
  const Eigen::Vector3d bent(0.0, 0.0, -0.025);  // a person turned the images' yaw 0.8 mrad
  // The warm-up: 30 readings, 9 of them bent.
  for (int k = 0; k < pipeline::GyroBias::kWarmUp; ++k) {
    EXPECT_EQ(bias.settled(), k >= pipeline::GyroBias::kSettleReadings);
    EXPECT_TRUE(give(k % 3 == 1 && k < 27 ? Eigen::Vector3d(clean() + bent) : clean()));
  }
  EXPECT_TRUE(bias.settled());
  testing::recordFigure("warm_up_error_rad_s", (bias.bias() - truth).norm(), 6);
  EXPECT_LT((bias.bias() - truth).norm(), 2e-3) << bias.bias().transpose();  // the mean: 7.5e-3
  // Then 150 pairs (5 s), 30 of them bent: those are not used.
  int refused = 0;
  for (int k = 0; k < 150; ++k)
    refused += !give(k % 5 == 0 ? Eigen::Vector3d(clean() + bent) : clean());
  EXPECT_EQ(refused, 30);
  testing::recordFigure("error_rad_s", (bias.bias() - truth).norm(), 6);
  testing::recordFigure("sigma_rad_s", bias.sigma(), 6);
  EXPECT_LT((bias.bias() - truth).norm(), 1e-3) << bias.bias().transpose();
  EXPECT_LT(bias.sigma(), 5e-4);
  // A reading no MEMS gyro gives is never used, even in the warm-up.
  pipeline::GyroBias fresh;
  EXPECT_FALSE(giveReading(fresh, Eigen::Vector3d(0.0, 0.0, 0.9), kSigma));
  EXPECT_EQ(fresh.readings(), 0);
}

// Pairs a person bent are also pairs the fit is less sure of: readings weigh the inverse of
// the variance they state, so bent readings that are most of the first ones do not take the
// start, and a run of them after it, each stating a wider sigma, gets no wider gate for it.
TEST(GyroBias, ReadingsThatStateALargerVarianceWeighLess) {
  const Eigen::Vector3d truth(-0.005, 0.002, 0.006);  // rad/s
  constexpr double kSigma = 0.002;  // rad/s per axis, a clean pair's (0.07 mrad)
  std::mt19937 rng(11);
  std::normal_distribution<double> noise(0.0, kSigma);
  const Eigen::Vector3d bent(0.0, 0.002, 0.02);  // a person turned the images' yaw 0.7 mrad
  pipeline::GyroBias bias;
  const auto give = [&](bool is_bent) {
    Eigen::Vector3d reading = truth + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    if (is_bent) reading += bent;
    return giveReading(bias, reading, is_bent ? 4.0 * kSigma : kSigma);
  };
  // The first ten: seven bent (the person came at once), three clean.
  for (int k = 0; k < pipeline::GyroBias::kSettleReadings; ++k) EXPECT_TRUE(give(k < 7));
  ASSERT_TRUE(bias.settled());
  const double start_error = (bias.bias() - truth).norm();
  testing::recordFigure("start_error_rad_s", start_error, 6);
  EXPECT_LT(start_error, 3.0 * kSigma) << bias.bias().transpose();  // the plain median: 0.02 off
  EXPECT_LT(start_error, 3.0 * bias.sigma());
  // The warm-up's clean rest, then a second of bent pairs in a row: refused.
  for (int k = pipeline::GyroBias::kSettleReadings; k < pipeline::GyroBias::kWarmUp; ++k)
    EXPECT_TRUE(give(false));
  int refused = 0;
  for (int k = 0; k < 30; ++k) refused += !give(true);
  testing::recordFigure("bent_refused", refused, 0);
  EXPECT_GE(refused, 28);
  EXPECT_LT((bias.bias() - truth).norm(), 1.5e-3) << bias.bias().transpose();
}

// While the camera translates, the images' yaw drifts with the walls' texture (the drift
// benchmark's rectangle: about 1 mrad/s), which straight driving alone cannot tell from the
// bias. Readings from translating pairs are kept apart: where the robot turned or stood in
// place, those pairs set the bias, and a robot that only drives gets the driving pairs' own,
// with a sigma that says it may be off by the drift.
TEST(GyroBias, TranslatingPairsDoNotSetTheBiasWherePairsInPlaceDo) {
  const Eigen::Vector3d truth(0.004, -0.006, 0.003);  // rad/s, IMU axes = camera axes here
  const Eigen::Vector3d drift(0.0, 0.0, 0.0015);      // the images' yaw while driving
  constexpr double kSigma = 0.002;
  std::mt19937 rng(5);
  std::normal_distribution<double> noise(0.0, kSigma);
  const auto give = [&](pipeline::GyroBias& bias, bool translating) {
    Eigen::Vector3d reading = truth + Eigen::Vector3d(noise(rng), noise(rng), noise(rng));
    if (translating) reading += drift;
    return giveReading(bias, reading, kSigma, translating);
  };
  // A turn in place (1 s), then 20 s of driving.
  pipeline::GyroBias bias;
  for (int k = 0; k < 30; ++k) EXPECT_TRUE(give(bias, false));
  for (int k = 0; k < 600; ++k) give(bias, true);
  const double yaw_error = std::abs(bias.bias().z() - truth.z());
  testing::recordFigure("after_driving_yaw_error_rad_s", yaw_error, 6);
  EXPECT_LT(yaw_error, 0.35 * drift.z()) << bias.bias().transpose();
  EXPECT_LT((bias.bias() - truth).head<2>().norm(), 5e-4) << bias.bias().transpose();
  // Driving only: the driving pairs' estimate, its sigma no smaller than the drift it may carry.
  pipeline::GyroBias driving;
  for (int k = 0; k < 600; ++k) give(driving, true);
  ASSERT_TRUE(driving.settled());
  EXPECT_NEAR(driving.bias().z(), truth.z() + drift.z(), 5e-4);
  EXPECT_GT(driving.sigma(), pipeline::GyroBias::kDrivingYawSigma / std::sqrt(3.0) * 0.99);
}

constexpr auto kSpline = synth::Interpolation::kSpline;

/// A robot driving straight ahead at 1 cm per frame (0.3 m/s at 30 fps) from the room's
/// centre, as the people benchmark's `driving`, `frames` frames.
std::vector<StampedPose> straightDrive(int frames) {
  std::ostringstream yaml;
  yaml << "frame_rate: 30\nsegments:\n  - frames: " << frames - 1
       << "\n    translation: {step_m: 0.01, direction: [1, 0, 0]}\n";
  return synth::generateTrajectory(synth::MotionScript::parse(yaml.str(), "drive"));
}

/// Per-pair yaw error (rad, RMS over the pairs) of the odometry over `frames`, the gyro's
/// `samples` given first, with PipelineOptions::gyro_fusion on or off.
double rmsPairYawError(const std::vector<StampedPose>& control, const std::vector<cv::Mat>& frames,
                       const Calibration& calibration, const std::vector<GyroSample>& samples,
                       bool fusion) {
  OdometryOptions options;
  options.pipeline.gyro_fusion = fusion;
  Odometry odometry(calibration, options);
  odometry.addGyro(samples);
  double sum_sq = 0.0;
  int pairs = 0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const auto r = odometry.process(
        frames[k], {control[k].timestamp, static_cast<std::int64_t>(k), false});
    EXPECT_TRUE(r.has_value()) << "frame " << k;
    if (!r || k == 0 || !r->relative.has_motion) continue;
    const Eigen::Matrix3d truth =
        control[k - 1].pose.linear().transpose() * control[k].pose.linear();
    const double e = rotationVector(truth.transpose() * r->relative.rotation).z();
    sum_sq += e * e;
    ++pairs;
  }
  EXPECT_EQ(pairs, static_cast<int>(frames.size()) - 1);
  return pairs > 0 ? std::sqrt(sum_sq / pairs) : 1.0;
}

// Two people crossing in front of a robot driving through a room (the people benchmark's
// `driving` on its indoor room, the people 1.5 s later): where they cover the direction of
// travel the images' yaw and direction of travel trade against each other, and the images
// alone turn the robot by up to 1 mrad a pair (docs/results/PEOPLE.md). The gyro does not see
// the people. Its bias is read from the images: the first second's pairs, before the people
// come, settle it (GyroBias), and the pairs the people bent do not move it after.
TEST(GyroFusion, PeopleCrossingInFrontOfADrivingRobotDoNotTurnIt) {
  if (!std::filesystem::exists(testing::indoorPhoto()))
    GTEST_SKIP() << "missing " << testing::indoorPhoto();
  constexpr int kFrames = 75;
  constexpr double kPeopleLater = 1.5;  // seconds on the walkers' clock
  const std::vector<StampedPose> control = straightDrive(kFrames);
  synth::Scene scene = synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kBox);
  const synth::Scene twin_scene = scene;
  scene.walkers = synth::parseWalkers("2,0.5,1.8,1.2");
  scene.walkers.min_distance_m = 1.5;
  scene.walkers.max_distance_m = 2.0;
  scene.walkers.seed = 1071;
  synth::DegradeOptions noise;
  noise.noise_sigma = 3.0;
  const auto render = [&](const synth::Scene& s) {
    const synth::Renderer renderer(s, Calibration{}, {.supersample = 1});
    std::vector<cv::Mat> frames;
    for (int k = 0; k < kFrames; ++k) {
      const double t = control[static_cast<std::size_t>(k)].timestamp;
      frames.push_back(
          synth::degrade(renderer.render(synth::poseAtTime(control, t, kSpline), t - kPeopleLater),
                         noise, static_cast<std::uint64_t>(k)));
    }
    return frames;
  };
  // A 200 Hz phone-class gyro, bias 0.5 deg/s, mounted 25 deg off.
  Calibration calibration;
  calibration.imu = ImuCalibration{};
  synth::GyroSimulation sim;
  sim.seed = 4;
  sim.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.436, Eigen::Vector3d(0.6, 0.0, 0.8)));
  calibration.imu->rotation = sim.rotation;
  const std::vector<GyroSample> samples =
      synth::simulateGyro(control, kSpline, sim, control.front().timestamp - 0.1,
                          control.back().timestamp + 0.1)
          .samples;

  const std::vector<cv::Mat> people = render(scene), twin = render(twin_scene);
  const double images = rmsPairYawError(control, people, calibration, samples, false);
  const double fused = rmsPairYawError(control, people, calibration, samples, true);
  const double twin_images = rmsPairYawError(control, twin, calibration, samples, false);
  const double twin_fused = rmsPairYawError(control, twin, calibration, samples, true);
  testing::recordFigure("people_images_yaw_rms_rad", images, 9);
  testing::recordFigure("people_fused_yaw_rms_rad", fused, 9);
  testing::recordFigure("twin_images_yaw_rms_rad", twin_images, 9);
  testing::recordFigure("twin_fused_yaw_rms_rad", twin_fused, 9);
  EXPECT_GT(images, 3.0 * twin_images) << "the people no longer bend the images' yaw";
  EXPECT_LT(fused, 0.4 * images);
  EXPECT_LT(fused, 2.0 * twin_images);  // the people cost less than the gyro gains
  EXPECT_LT(twin_fused, twin_images);   // and without them the gyro still helps
}

}  // namespace
}  // namespace omnipose
