// The camera-gyro calibration measured from frames and a gyro (imu_estimation.hpp) against
// renders of a camera turning about changing axes, whose gyro the renderer wrote from the
// exact motion with a mounting, a clock offset, noise and a bias.
#include "omnipose/calibrate/imu_estimation.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sys/wait.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <sstream>
#include <vector>

#include "omnipose/so3.hpp"
#include "omnipose/synth/synth.hpp"
#include "test_files.hpp"

using ::testing::HasSubstr;

namespace omnipose::calibrate {
namespace {

Calibration calibrationWithReadout(double readout_s) {
  Calibration c;
  c.sensor.readout_s = readout_s;
  return c;
}

struct Recording {
  std::vector<StampedPose> trajectory;
  std::vector<cv::Mat> images;
  std::vector<double> times;
  GyroRecording gyro;
};

/// The frames at 30 fps of `script`, rendered from the bundled indoor photo with sensor noise
/// (rows read out over `readout_s`, along the smooth motion between frames), and the gyro of
/// that motion.
Recording render(const synth::GyroSimulation& gyro, const synth::MotionScript& script, double readout_s) {
  const auto trajectory = synth::generateTrajectory(script);
  const synth::Renderer renderer(
      synth::Scene::load(std::filesystem::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg",
                         synth::SceneKind::kSphere),
      calibrationWithReadout(readout_s), {.supersample = 2});
  synth::DegradeOptions noise;
  noise.noise_sigma = 2.0;
  Recording r;
  r.trajectory = trajectory;
  for (std::size_t k = 0; k < trajectory.size(); ++k) {
    const double t0 = trajectory[k].timestamp;
    const auto pose_at = [&](double t) {
      return synth::poseAtTime(trajectory, t0 + t, synth::Interpolation::kSmooth);
    };
    r.images.push_back(synth::degrade(renderer.render(pose_at, readout_s), noise, k));
    r.times.push_back(trajectory[k].timestamp);
  }
  r.gyro = synth::simulateGyro(trajectory, synth::Interpolation::kSmooth, gyro, -0.2,
                               trajectory.back().timestamp + 0.2);
  return r;
}

/// `frames` frames of a camera turning 1-6 deg per frame about a random axis drawn anew each
/// frame (within 20 deg of the start), or about z only (`one_axis`), or (`shaking`) turning
/// 0.5-3.5 deg per frame about z on a base shaking 0.5 deg at 1-9 Hz: render() of it.
Recording render(const synth::GyroSimulation& gyro, int frames, bool one_axis, double readout_s = 0.0,
                 int seed = 5, bool shaking = false) {
  std::ostringstream yaml;
  yaml << "frame_rate: 30\nvibration: {amplitude_deg: 0.5, min_hz: 1, max_hz: 9, seed: " << seed << "}\nsegments:\n";
  for (int k = 0; k + 1 < frames; ++k)
    yaml << "  - frames: 1\n    rotation: {axis: z, step_deg: " << 2.0 + 1.5 * std::sin(k * 0.6 + seed) << ", sign: positive}\n";
  synth::MotionScript script = shaking ? synth::MotionScript::parse(yaml.str()) : synth::MotionScript::parse(
      "seed: " + std::to_string(seed) + "\nframe_rate: 30\nsegments:\n  - frames: 100\n    rotation: {axis: " +
      (one_axis ? "z, step_deg: [1, 6], sign: random}\n" : "random, step_deg: [1, 6], bound_deg: 20}\n"));
  script.frames = frames;
  return render(gyro, script, readout_s);
}

/// The bias `gyro` drew for recording `r` (IMU axes, rad/s): its first sample without noise
/// less the one without noise and bias.
Eigen::Vector3d drawnBias(const Recording& r, synth::GyroSimulation gyro) {
  gyro.noise_density = 0.0;
  const auto first = [&](const synth::GyroSimulation& g) {
    return synth::simulateGyro(r.trajectory, synth::Interpolation::kSmooth, g, 0.0, 0.0).samples.front().rate;
  };
  const Eigen::Vector3d biased = first(gyro);
  gyro.bias = 0.0;
  return biased - first(gyro);
}

synth::GyroSimulation mountedGyro() {
  synth::GyroSimulation gyro;  // 200 Hz, 0.005 deg/s/sqrt(Hz), bias 0.5 deg/s
  gyro.time_offset_s = 0.0123;
  gyro.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.7, Eigen::Vector3d(1.0, -2.0, 0.5).normalized()));
  gyro.seed = 9;
  return gyro;
}

TEST(ImuEstimation, FindsTheMountingTheClockOffsetAndTheBias) {
  const synth::GyroSimulation gyro = mountedGyro();
  const Recording r = render(gyro, 40, false);
  const ImuEstimate e = estimateImuCalibration(Calibration{}, r.images, r.times, r.gyro.samples);
  ASSERT_TRUE(e.found) << e.summary;
  const double rotation_error_deg =
      rotationVector(e.imu.rotation.toRotationMatrix().transpose() * gyro.rotation.toRotationMatrix()).norm() *
      180.0 / std::numbers::pi;
  ::testing::Test::RecordProperty("rotation_error_deg", std::to_string(rotation_error_deg));
  ::testing::Test::RecordProperty("summary", e.summary);
  ::testing::Test::RecordProperty("time_offset_error_ms", std::to_string(1e3 * (e.imu.time_offset_s - gyro.time_offset_s)));
  EXPECT_LT(rotation_error_deg, 0.2) << e.summary;
  EXPECT_NEAR(e.imu.time_offset_s, gyro.time_offset_s, 1e-4) << e.summary;
  const Eigen::Vector3d bias = drawnBias(r, gyro);
  EXPECT_NEAR(bias.norm(), gyro.bias, 1e-12);
  EXPECT_LT((e.bias - bias).norm(), 4 * e.bias_sigma.x()) << e.summary;
  EXPECT_GE(e.pairs, 30);
  EXPECT_LT(e.rotation_sigma_deg, 0.2);
  EXPECT_LT(e.time_offset_sigma_s, 1e-4);

  // A gap of 0.1 s in the gyro's recording (a USB hiccup) leaves out the pairs near it only.
  std::vector<GyroSample> gappy;
  for (const GyroSample& s : r.gyro.samples)
    if (s.t < 0.6 || s.t > 0.7) gappy.push_back(s);
  const ImuEstimate g = estimateImuCalibration(Calibration{}, r.images, r.times, gappy);
  ASSERT_TRUE(g.found) << g.summary;
  EXPECT_LT(g.pairs, e.pairs);
  EXPECT_GE(g.pairs, e.pairs - 14) << "at most the pairs within 0.11 s of the gap";
  EXPECT_NEAR(g.imu.time_offset_s, gyro.time_offset_s, 1e-4) << g.summary;
}

TEST(ImuEstimation, ARecordingThatTurnsAboutOneAxisCannotTellTheMounting) {
  const Recording r = render(mountedGyro(), 25, true);
  const ImuEstimate e = estimateImuCalibration(Calibration{}, r.images, r.times, r.gyro.samples);
  EXPECT_FALSE(e.found);
  EXPECT_THAT(e.summary, HasSubstr("two axes")) << e.summary;
}

TEST(ImuEstimation, TooFewPairsOrAGyroThatMissesTheFramesIsSaid) {
  const Recording r = render(mountedGyro(), 12, false);
  // The gyro stops after the fourth frame.
  std::vector<GyroSample> early;
  for (const GyroSample& s : r.gyro.samples)
    if (s.t < r.times[4]) early.push_back(s);
  const ImuEstimate e = estimateImuCalibration(Calibration{}, r.images, r.times, early);
  EXPECT_FALSE(e.found);
  EXPECT_THAT(e.summary, HasSubstr("inside the gyro's recording without a gap")) << e.summary;
  ImuSearchOptions bad;
  bad.fine_step_s = 0.0;
  EXPECT_THROW(estimateImuCalibration(Calibration{}, r.images, r.times, r.gyro.samples, bad),
               std::invalid_argument);
  EXPECT_THROW(estimateImuCalibration(Calibration{}, r.images, std::span(r.times).first(3), r.gyro.samples),
               std::invalid_argument);
  const std::vector<double> exposures(3, 0.01);  // frames' exposures must be one per frame
  EXPECT_THROW(estimateImuCalibration(Calibration{}, r.images, r.times, r.gyro.samples, {}, exposures),
               std::invalid_argument);
}

// omnipose-calibrate --imu-from on a dataset written like a robot's recording: the imu section
// it writes is the estimate's; without imu.csv it names the file and writes nothing.
TEST(ImuCli, WritesTheCalibrationWithTheImuSectionOrNamesWhatIsMissing) {
  const synth::GyroSimulation gyro = mountedGyro();
  const Recording r = render(gyro, 40, false);
  const auto root = std::filesystem::temp_directory_path() / ("omnipose_imu_cli_" + std::to_string(::getpid()));
  std::filesystem::remove_all(root);
  {
    synth::DatasetWriter writer(root / "run", Calibration{}, 0);
    for (std::size_t k = 0; k < r.images.size(); ++k) writer.addFrame(r.images[k], r.trajectory[k]);
    writer.writeGyro(r.gyro.samples);
    writer.finish();
  }
  const auto calibrate = [&](const std::string& dataset, const std::string& out) {
    const std::string command = std::string(OMNIPOSE_BINARY_DIR) + "/bin/omnipose-calibrate --imu-from " +
                                dataset + " --out " + out + " > " + (root / "log").string() + " 2>&1";
    const int status = std::system(command.c_str());
    return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  };
  ASSERT_EQ(calibrate((root / "run").string(), (root / "cal.yaml").string()), 0)
      << omnipose::testing::readText(root / "log");
  const std::string log = omnipose::testing::readText(root / "log");
  EXPECT_THAT(log, HasSubstr("40 frames and"));
  EXPECT_THAT(log, HasSubstr("gyro bias"));
  const Calibration written = Calibration::load(root / "cal.yaml");
  ASSERT_TRUE(written.imu.has_value());
  EXPECT_NEAR(written.imu->time_offset_s, gyro.time_offset_s, 1e-4);
  EXPECT_LT(rotationVector(written.imu->rotation.toRotationMatrix().transpose() * gyro.rotation.toRotationMatrix()).norm(),
            0.2 * std::numbers::pi / 180.0);

  std::filesystem::remove(root / "run" / "imu.csv");
  EXPECT_EQ(calibrate((root / "run").string(), (root / "none.yaml").string()), 1);
  EXPECT_THAT(omnipose::testing::readText(root / "log"), HasSubstr((root / "run" / "imu.csv").string() + ": missing"));
  EXPECT_FALSE(std::filesystem::exists(root / "none.yaml"));
  std::filesystem::remove_all(root);
}

// A pool: the camera turning about random axes and turning with a shaking base, seeds 1-3,
// global shutter and a rolling shutter of 0.8 frame (its readout given 3 % short). Each is
// measured, a rolling shutter through the pairs registered again with the gyro's rows, then
// its readout, clock and mounting from the pixels: the readout within the 0.5 %, the
// clock within 0.1 ms, the mounting within the 0.2 deg (0.18 deg on shaking seed 1
// with a global shutter: the shaking base turns little about its weakest axis in 40 frames).
TEST(ImuEstimation, APoolOfRecordingsGlobalOrRollingShutterIsMeasured) {
  for (const bool shaking : {false, true}) {
    for (const double readout : {0.0, 0.0267}) {
      for (const int seed : {1, 2, 3}) {
        synth::GyroSimulation gyro = mountedGyro();
        gyro.seed = 100 + seed;
        const Recording r = render(gyro, 40, false, readout, seed, shaking);
        // A rolling shutter's readout given 3 % short (as --readout-from leaves it).
        const ImuEstimate e = estimateImuCalibration(calibrationWithReadout(0.97 * readout), r.images,
                                                     r.times, r.gyro.samples);
        const double rotation_error_deg =
            rotationVector(e.imu.rotation.toRotationMatrix().transpose() * gyro.rotation.toRotationMatrix()).norm() *
            180.0 / std::numbers::pi;
        const double offset_error_s = e.imu.time_offset_s - gyro.time_offset_s;
        const std::string name = std::string(shaking ? "shaking" : "random_axes") +
                                 (readout > 0.0 ? "_rolling_" : "_global_") + std::to_string(seed);
        ::testing::Test::RecordProperty(name, (e.found ? "found" : "refused") + std::string(": rotation error ") +
                                                  std::to_string(rotation_error_deg) + " deg, offset error " +
                                                  std::to_string(1e3 * offset_error_s) + " ms, readout " +
                                                  std::to_string(e.readout_s) + " s; " + e.summary + "; " +
                                                  e.pixels_summary);
        EXPECT_TRUE(e.found) << name << ": " << e.summary;
        if (!e.found) continue;
        EXPECT_LT(rotation_error_deg, 0.2) << name << ": " << e.summary;
        EXPECT_LT(std::abs(offset_error_s), 1e-4) << name << ": " << e.summary;
        EXPECT_THAT(e.pixels_summary, HasSubstr("from the pixels")) << name;
        if (readout == 0.0) {
          EXPECT_EQ(e.readout_s, 0.0) << name;
        } else {
          EXPECT_NEAR(e.readout_s, readout, 0.005 * readout) << name << ": " << e.pixels_summary;
        }
      }
    }
  }
}

// The readout, the clock offset and the mounting from the pixels (photometric_timing.hpp) on a
// shaking base whose last row is read first: from a readout 5 % long or short, an offset
// 0.3 ms late and a mounting 0.3 deg off (held to it with 0.5 deg), all land on the truth
// (0.5 %, 0.05 ms, 0.1 deg), the same from either side.
TEST(PhotometricTiming, FindsTheReadoutAndTheOffsetFromRoughStarts) {
  synth::GyroSimulation gyro = mountedGyro();
  gyro.seed = 41;
  constexpr double kReadout = -0.0267;
  const Recording r = render(gyro, 30, false, kReadout, 4, true);
  const Eigen::Vector3d bias = drawnBias(r, gyro);
  std::vector<double> found;
  for (const double start : {1.05, 0.95}) {
    Calibration c = calibrationWithReadout(start * kReadout);
    const Eigen::Quaterniond off(Eigen::AngleAxisd(0.3 * std::numbers::pi / 180.0, Eigen::Vector3d(1, 2, 2) / 3.0));
    c.imu = ImuCalibration{.rotation = off * gyro.rotation, .time_offset_s = gyro.time_offset_s + 3e-4,
                           .gyro_noise_density = std::nullopt};
    const PhotometricTiming t =
        refineTimingFromPixels(c, r.images, r.times, r.gyro.samples, bias, 0.5 * std::numbers::pi / 180.0);
    ::testing::Test::RecordProperty("start_" + std::to_string(start), t.summary);
    ASSERT_TRUE(t.found) << t.summary;
    EXPECT_NEAR(t.readout_s, kReadout, 0.005 * std::abs(kReadout)) << t.summary;
    EXPECT_NEAR(t.time_offset_s, gyro.time_offset_s, 5e-5) << t.summary;
    EXPECT_LT(t.readout_sigma_s, 0.005 * std::abs(kReadout)) << t.summary;
    EXPECT_LT(t.time_offset_sigma_s, 5e-5) << t.summary;
    const double mounting_error_deg =
        rotationVector(t.rotation.toRotationMatrix().transpose() * gyro.rotation.toRotationMatrix()).norm() * 180.0 /
        std::numbers::pi;
    EXPECT_LT(mounting_error_deg, 0.1) << t.summary;
    EXPECT_LT(t.rotation_sigma_deg, 0.1) << t.summary;
    EXPECT_EQ(t.pairs, 29);
    EXPECT_LT(t.residual_rms, 0.5) << t.summary;
    found.push_back(t.readout_s);
  }
  EXPECT_NEAR(found[0], found[1], 1e-5) << "the same minimum from either side";
}

// A global shutter: its readout stays 0, and the clock and the mounting land on the truth from
// 0.3 ms and 0.3 deg off.
TEST(PhotometricTiming, AGlobalShutterKeepsItsReadoutAndFindsTheClockAndTheMounting) {
  synth::GyroSimulation gyro = mountedGyro();
  gyro.seed = 43;
  const Recording r = render(gyro, 30, false, 0.0, 6, true);
  Calibration c = calibrationWithReadout(0.0);
  const Eigen::Quaterniond off(Eigen::AngleAxisd(0.3 * std::numbers::pi / 180.0, Eigen::Vector3d(2, -1, 2) / 3.0));
  c.imu = ImuCalibration{.rotation = off * gyro.rotation, .time_offset_s = gyro.time_offset_s - 3e-4,
                         .gyro_noise_density = std::nullopt};
  const PhotometricTiming t =
      refineTimingFromPixels(c, r.images, r.times, r.gyro.samples, drawnBias(r, gyro), 0.5 * std::numbers::pi / 180.0);
  ::testing::Test::RecordProperty("summary", t.summary);
  ASSERT_TRUE(t.found) << t.summary;
  EXPECT_EQ(t.readout_s, 0.0);
  EXPECT_EQ(t.readout_sigma_s, 0.0);
  EXPECT_THAT(t.summary, ::testing::Not(HasSubstr("readout"))) << t.summary;
  EXPECT_NEAR(t.time_offset_s, gyro.time_offset_s, 5e-5) << t.summary;
  EXPECT_LT(rotationVector(t.rotation.toRotationMatrix().transpose() * gyro.rotation.toRotationMatrix()).norm() * 180.0 /
                std::numbers::pi,
            0.1)
      << t.summary;
  EXPECT_LT(t.iterations, PhotometricTimingOptions{}.max_iterations) << "converged: " << t.summary;
}

// A turn at a steady rate cannot tell the clock (the rotation between any two instants the same
// time apart is the same): refused, saying so. Too few pairs inside the gyro's recording are
// said, and so is a frame of another size; a calibration without an imu section, a prior not
// > 0, invalid options and mismatched counts throw.
TEST(PhotometricTiming, ASteadyTurnOrTooFewPairsIsRefused) {
  const synth::GyroSimulation gyro = mountedGyro();
  synth::MotionScript steady = synth::MotionScript::parse(
      "frame_rate: 30\nsegments:\n  - frames: 24\n    rotation: {axis: z, step_deg: 3, sign: positive}\n");
  steady.frames = 24;
  const Recording r = render(gyro, steady, 0.0267);
  Calibration c = calibrationWithReadout(0.0267);
  c.imu = ImuCalibration{.rotation = gyro.rotation, .time_offset_s = gyro.time_offset_s,
                         .gyro_noise_density = std::nullopt};
  const Eigen::Vector3d bias = drawnBias(r, gyro);
  constexpr double kSigma = 0.01;  // radians, the mounting's prior
  const PhotometricTiming t = refineTimingFromPixels(c, r.images, r.times, r.gyro.samples, bias, kSigma);
  ::testing::Test::RecordProperty("steady", t.summary);
  EXPECT_FALSE(t.found) << t.summary;
  EXPECT_THAT(t.summary, HasSubstr("not determined")) << t.summary;

  std::vector<GyroSample> early;
  for (const GyroSample& s : r.gyro.samples)
    if (s.t < r.times[6]) early.push_back(s);
  const PhotometricTiming few = refineTimingFromPixels(c, r.images, r.times, early, bias, kSigma);
  EXPECT_FALSE(few.found);
  EXPECT_THAT(few.summary, HasSubstr("inside the gyro's recording without a gap")) << few.summary;

  std::vector<cv::Mat> panoramas = r.images;  // not omni images: said, not read out of bounds
  panoramas[3] = cv::Mat(110, 1100, CV_8U, cv::Scalar(0));
  const PhotometricTiming other = refineTimingFromPixels(c, panoramas, r.times, r.gyro.samples, bias, kSigma);
  EXPECT_FALSE(other.found);
  EXPECT_THAT(other.summary, HasSubstr("frame 3 is 1100x110, not the calibration's omni image")) << other.summary;

  EXPECT_THROW(refineTimingFromPixels(c, r.images, r.times, r.gyro.samples, bias, 0.0), std::invalid_argument);
  Calibration no_imu = c;
  no_imu.imu.reset();
  EXPECT_THROW(refineTimingFromPixels(no_imu, r.images, r.times, r.gyro.samples, bias, kSigma), std::invalid_argument);
  PhotometricTimingOptions bad;
  bad.pixels_per_frame = 0;
  EXPECT_THROW(refineTimingFromPixels(c, r.images, r.times, r.gyro.samples, bias, kSigma, bad), std::invalid_argument);
  EXPECT_THROW(refineTimingFromPixels(c, r.images, std::span(r.times).first(3), r.gyro.samples, bias, kSigma),
               std::invalid_argument);
}

}  // namespace
}  // namespace omnipose::calibrate
