// The robot's gyro beyond the rolling shutter, against the exact renderer: its bias measured
// from the images, and a gap the images cannot bridge (the view changed: a camera knocked,
// the lights) bridged by the gyro instead of starting a new segment (DESIGN.md section 3,
// "The gyro's bias and bridging").
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <unistd.h>
#include <vector>

#include "omnipose/odometry.hpp"
#include "omnipose/so3.hpp"
#include "omnipose/synth/gyro.hpp"
#include "omnipose/synth/synth.hpp"
#include "render_fixture.hpp"

namespace omnipose {
namespace {
namespace fs = std::filesystem;
constexpr auto kSpline = synth::Interpolation::kSpline;

/// A turn of 1.5 deg/frame at 30 fps on a base shaking 0.5 deg at 1-9 Hz, `frames` frames.
std::vector<StampedPose> turn(int frames) {
  std::ostringstream yaml;
  yaml << "frame_rate: 30\n"
          "vibration: {amplitude_deg: 0.5, min_hz: 1, max_hz: 9, components: 3, seed: 11}\n"
          "segments:\n  - frames: "
       << frames - 1 << "\n    rotation: {axis: z, step_deg: 1.5, sign: positive}\n";
  return synth::generateTrajectory(synth::MotionScript::parse(yaml.str(), "turn"));
}

/// A 200 Hz phone-class gyro (0.005 deg/s/sqrt(Hz), bias 0.5 deg/s in the seed's direction)
/// mounted 25 deg off, on the motion `control` (spline); its calibration in `imu`.
std::vector<GyroSample> gyroOf(const std::vector<StampedPose>& control, ImuCalibration& imu,
                               Eigen::Vector3d& true_bias) {
  synth::GyroSimulation sim;
  sim.seed = 4;
  sim.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.436, Eigen::Vector3d(0.6, 0.0, 0.8)));
  imu.rotation = sim.rotation;
  std::vector<GyroSample> samples =
      synth::simulateGyro(control, kSpline, sim, control.front().timestamp - 0.1,
                          control.back().timestamp + 0.1)
          .samples;
  // The bias the simulation drew: the samples' mean difference from the exact rate.
  true_bias.setZero();
  const Eigen::Matrix3d imu_from_camera = sim.rotation.toRotationMatrix().transpose();
  for (const GyroSample& s : samples)
    true_bias += s.rate - imu_from_camera * synth::angularVelocityAtTime(control, s.t, kSpline);
  true_bias /= static_cast<double>(samples.size());
  return samples;
}

/// The frames of `control` (spline) from `photo`, global shutter, sensor noise 2 grey levels.
std::vector<cv::Mat> render(const std::vector<StampedPose>& control, const fs::path& photo,
                            std::size_t from, std::size_t to) {
  const synth::Renderer renderer(synth::Scene::load(photo, synth::SceneKind::kSphere),
                                 Calibration{}, {.supersample = 1});
  synth::DegradeOptions noise;
  noise.noise_sigma = 2.0;
  std::vector<cv::Mat> frames;
  for (std::size_t k = from; k < to; ++k)
    frames.push_back(synth::degrade(
        renderer.render(synth::poseAtTime(control, control[k].timestamp, kSpline)), noise, k));
  return frames;
}

TEST(GyroBias, IsMeasuredFromTheImages) {
  const std::vector<StampedPose> control = turn(90);
  Calibration calibration;
  calibration.imu = ImuCalibration{};
  Eigen::Vector3d true_bias;
  const std::vector<GyroSample> samples = gyroOf(control, *calibration.imu, true_bias);
  const std::vector<cv::Mat> frames = render(control, testing::indoorPhoto(), 0, control.size());
  Odometry odometry(calibration, {});
  odometry.addGyro(std::span(samples).first(samples.size() / 2));
  odometry.addGyro(std::span(samples).subspan(samples.size() / 2));
  for (std::size_t k = 0; k < frames.size(); ++k)
    ASSERT_TRUE(odometry.process(frames[k], {control[k].timestamp}).has_value());
  const GyroCounters c = odometry.gyroCounters();
  const double error = (c.bias - true_bias).norm();
  ::testing::Test::RecordProperty("bias_true_rad_s", std::to_string(true_bias.norm()));
  ::testing::Test::RecordProperty("bias_error_rad_s", std::to_string(error));
  ::testing::Test::RecordProperty("bias_sigma_rad_s", std::to_string(c.bias_sigma));
  EXPECT_EQ(c.bias_readings, 89);
  EXPECT_NEAR(true_bias.norm(), 0.5 * std::numbers::pi / 180.0, 2e-4);
  // Within 0.02 deg/s of 0.5 (a degree of heading per 50 s of bridging), and its sigma says so.
  EXPECT_LT(error, 0.02 * std::numbers::pi / 180.0);
  EXPECT_LT(c.bias_sigma, 2e-3);
  EXPECT_LT(error, 4.0 * c.bias_sigma);
  EXPECT_EQ(c.frames_with_gyro, 0) << "a global shutter has no rows to correct";
  EXPECT_EQ(c.frames_without_gyro, 0);
}

TEST(GyroBridge, AGapTheImagesCannotBridgeIsBridgedByTheGyro) {
  // The camera is knocked (its view mirrored) after frame 29: nothing of the frames before is
  // found in the frames after. Without the gyro the chain starts a new segment; with it, it
  // goes on with the gyro's rotation across the frames not believed.
  const std::vector<StampedPose> control = turn(50);
  const fs::path mirrored =
      fs::temp_directory_path() / ("omnipose_mirrored_" + std::to_string(::getpid()) + ".png");
  cv::Mat photo = cv::imread(testing::indoorPhoto().string());
  cv::flip(photo, photo, 1);
  ASSERT_TRUE(cv::imwrite(mirrored.string(), photo));
  std::vector<cv::Mat> frames = render(control, testing::indoorPhoto(), 0, 30);
  for (cv::Mat& f : render(control, mirrored, 30, control.size())) frames.push_back(f);
  fs::remove(mirrored);

  Calibration with_gyro;
  with_gyro.imu = ImuCalibration{};
  Eigen::Vector3d true_bias;
  const std::vector<GyroSample> samples = gyroOf(control, *with_gyro.imu, true_bias);
  for (const bool gyro : {false, true}) {
    Odometry odometry(gyro ? with_gyro : Calibration{}, {});
    odometry.addGyro(samples);  // ignored without the imu section
    Eigen::Matrix3d last = Eigen::Matrix3d::Identity();
    std::vector<int> implausible;
    for (std::size_t k = 0; k < frames.size(); ++k) {
      const auto r = odometry.process(frames[k], {control[k].timestamp});
      if (!r) {
        // Foreign frames are first taken for a glitching camera's (PlausibilityOptions).
        EXPECT_EQ(r.error().code(), ErrorCode::kImplausible) << k;
        implausible.push_back(static_cast<int>(k));
        continue;
      }
      last = r->pose.linear();
      if (k < 30 || k > 35) {
        EXPECT_EQ(r->state, k == 0 ? TrackState::kSegmentStart : TrackState::kTracked) << k;
        EXPECT_EQ(r->segment, k < 30 || gyro ? 0 : 1) << k;
        continue;
      }
      // After max_rejected (5) such frames in a row the view changed for good.
      EXPECT_EQ(k, 35u);
      if (!gyro) {
        EXPECT_EQ(r->state, TrackState::kLost);
        EXPECT_EQ(r->segment, 1);
        continue;
      }
      EXPECT_EQ(r->state, TrackState::kGyroBridged);
      EXPECT_EQ(r->segment, 0);
      EXPECT_EQ(r->reference_sequence, 29);
      EXPECT_EQ(r->relative.estimate.status, FitStatus::kDegraded);
      EXPECT_EQ(r->relative.estimate.tau, Eigen::Vector3d::Zero());
      EXPECT_TRUE(std::isinf(r->relative.estimate.covariance(3, 3)));
      const double variance = r->relative.estimate.covariance(0, 0);
      EXPECT_GT(variance, 0.0);
      EXPECT_LT(variance, 1e-8);
    }
    EXPECT_EQ(implausible, (std::vector<int>{30, 31, 32, 33, 34}));
    const GyroCounters c = odometry.gyroCounters();
    EXPECT_EQ(c.frames_gyro_bridged, gyro ? 1 : 0);
    if (!gyro) continue;
    // The chain went on across the gap: the last frame's attitude from the first frame's.
    const auto at = [&](std::size_t k) -> Eigen::Matrix3d {
      return synth::poseAtTime(control, control[k].timestamp, kSpline).linear();
    };
    const double error =
        rotationVector(last.transpose() * at(0).transpose() * at(frames.size() - 1)).norm();
    ::testing::Test::RecordProperty("end_error_rad", std::to_string(error));
    EXPECT_LT(error, 1e-3);
  }
}

}  // namespace
}  // namespace omnipose
