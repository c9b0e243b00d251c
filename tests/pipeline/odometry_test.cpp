// The frame-to-pose policy (omnipose/odometry.hpp) against the exact renderer: keyframes
// hold while the robot stands still or turns in place, so the chained attitude does not
// drift; a frame after a gap (one bad frame, ten, a 2-second outage during a turn) is found
// again against the keyframe with the heading kept; only an unrelated view starts a new
// segment; translation and tilt switch the keyframe.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <map>
#include <numbers>
#include <vector>

#include "allocation_counter.hpp"
#include "omnipose/odometry.hpp"
#include "omnipose/so3.hpp"
#include "omnipose/synth/synth.hpp"
#include "render_fixture.hpp"

using ::testing::HasSubstr;

namespace omnipose {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// Renders omni frames (8-bit) at the given camera poses, each with its own sensor noise.
/// A pose is rendered once (the tests revisit poses; only the noise differs).
class Renderings {
 public:
  explicit Renderings(synth::SceneKind kind = synth::SceneKind::kSphere)
      : renderer_(synth::Scene::load(testing::indoorPhoto(), kind), Calibration{},
                  {synth::OutputKind::kOmni, /*supersample=*/2}) {}

  cv::Mat frame(const Eigen::Isometry3d& pose, int seed) {
    std::array<double, 12> key;
    Eigen::Map<Eigen::Matrix<double, 3, 4>>(key.data()) = pose.matrix().topRows<3>();
    auto it = rendered_.find(key);
    if (it == rendered_.end()) it = rendered_.emplace(key, renderer_.render(pose)).first;
    synth::DegradeOptions noise;
    noise.noise_sigma = 2.0;
    return synth::degrade(it->second, noise, static_cast<std::uint64_t>(seed));
  }

 private:
  synth::Renderer renderer_;
  std::map<std::array<double, 12>, cv::Mat> rendered_;
};

Eigen::Isometry3d attitude(double roll, double pitch, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(pitch, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(roll, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  return T;
}

double rotationError(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& truth) {
  return rotationVector(estimate.linear().transpose() * truth.linear()).norm();
}

/// The default options with keyframes on.
OdometryOptions withKeyframes() {
  OdometryOptions options;
  options.keyframes.slots = 4;
  return options;
}

OdometryResult processOk(Odometry& odometry, const cv::Mat& frame, double t,
                         bool gap_before = false) {
  auto r = odometry.process(frame, {t, -1, gap_before});
  EXPECT_TRUE(r.has_value()) << (r ? "" : r.error().c_str());
  return r ? *r : OdometryResult{};
}

/// Odometry with the default options after two frames of the test scene: at rest, then
/// turned 4 degrees (yaw).
struct TrackedTurn {
  Renderings scene;
  Odometry odometry{Calibration{}, {}};
  const Eigen::Isometry3d turned = attitude(0, 0, 4 * kDeg);
  OdometryResult before;

  TrackedTurn() {
    processOk(odometry, scene.frame(Eigen::Isometry3d::Identity(), 0), 0.0);
    before = processOk(odometry, scene.frame(turned, 1), 1 / 30.0);
  }
};

/// An omni frame of the default calibration's size, every pixel `grey`.
cv::Mat uniformFrame(int grey) {
  return cv::Mat(Calibration{}.omni.image_height, Calibration{}.omni.image_width, CV_8UC1,
                 cv::Scalar(grey));
}

TEST(Odometry, StandingStillKeepsItsFirstKeyframeAndDoesNotDrift) {
  Renderings scene;
  Odometry odometry(Calibration{}, withKeyframes());
  double worst = 0.0;
  for (int k = 0; k < 40; ++k) {
    const OdometryResult r = processOk(odometry, scene.frame(Eigen::Isometry3d::Identity(), k), k / 30.0);
    EXPECT_EQ(r.keyframe_sequence, 0) << "frame " << k;
    EXPECT_EQ(r.frames_since_keyframe, k);
    EXPECT_EQ(r.segment, 0);
    if (k > 0) {
      EXPECT_EQ(r.state, TrackState::kTracked);
    }
    worst = std::max(worst, rotationError(r.pose, Eigen::Isometry3d::Identity()));
  }
  ::testing::Test::RecordProperty("worst_chained_error_rad", std::to_string(worst));
  EXPECT_LT(worst, 3e-4) << "each frame is one registration away from the keyframe";
}

TEST(Odometry, AYawSwingAndBackStaysOnOneKeyframeAndEndsWhereItBegan) {
  Renderings scene;
  Odometry odometry(Calibration{}, withKeyframes());
  std::vector<double> yaw;
  for (int k = 0; k <= 10; ++k) yaw.push_back(6.0 * k * kDeg);      // to +60 degrees
  for (int k = 9; k >= -10; --k) yaw.push_back(6.0 * k * kDeg);     // to -60
  for (int k = -9; k <= 0; ++k) yaw.push_back(6.0 * k * kDeg);      // back to 0
  OdometryResult r;
  double worst = 0.0;
  for (std::size_t k = 0; k < yaw.size(); ++k) {
    const Eigen::Isometry3d truth = attitude(0, 0, yaw[k]);
    r = processOk(odometry, scene.frame(truth, static_cast<int>(k)), k / 30.0);
    EXPECT_EQ(r.keyframe_sequence, 0) << "a yaw does not change the view";
    worst = std::max(worst, rotationError(r.pose, truth));
  }
  ::testing::Test::RecordProperty("worst_chained_error_rad", std::to_string(worst));
  EXPECT_LT(rotationError(r.pose, Eigen::Isometry3d::Identity()), 3e-4);
  EXPECT_LT(worst, 5e-4);
}

/// Per-pair rotation error RMS and end-point error of a run of `options` over the swing
/// +-30 deg with a slight wobble (roll and pitch up to 0.6 deg), ending where it began.
struct SwingRun {
  double pair_rms = 0.0, pose_rms = 0.0, worst = 0.0;
  int anchored = 0;  ///< frames whose keyframe was not the previous frame
};
SwingRun runSwing(Renderings& scene, const OdometryOptions& options) {
  std::vector<Eigen::Isometry3d> truth;
  for (int k = 0; k <= 60; ++k) {
    const double phase = 2.0 * std::numbers::pi * k / 60.0;
    truth.push_back(attitude(0.6 * kDeg * std::sin(3 * phase), 0.4 * kDeg * std::sin(5 * phase),
                             30.0 * kDeg * std::sin(phase)));
  }
  Odometry odometry(Calibration{}, options);
  SwingRun run;
  double sum = 0.0, pose_sum = 0.0;
  for (std::size_t k = 0; k < truth.size(); ++k) {
    const OdometryResult r =
        processOk(odometry, scene.frame(truth[k], static_cast<int>(k)), static_cast<double>(k) / 30.0);
    if (k > 0) {
      const Eigen::Matrix3d pair = truth[k - 1].linear().transpose() * truth[k].linear();
      sum += rotationVector(r.relative.rotation.transpose() * pair).squaredNorm();
      if (r.keyframe_sequence != r.reference_sequence) ++run.anchored;
    }
    const double error = rotationError(r.pose, truth[k]);
    run.worst = std::max(run.worst, error);
    pose_sum += error * error;
  }
  run.pair_rms = std::sqrt(sum / static_cast<double>(truth.size() - 1));
  run.pose_rms = std::sqrt(pose_sum / static_cast<double>(truth.size()));
  return run;
}

TEST(Odometry, KeyframesAnchorThePoseWithoutCostingThePairs) {
  Renderings scene;
  OdometryOptions frame_to_frame;
  frame_to_frame.keyframes.slots = 0;
  const SwingRun chained = runSwing(scene, frame_to_frame);
  const SwingRun anchored = runSwing(scene, {});  // the default: keyframes, anchor_gain 0.1
  for (const auto& [name, run] : {std::pair{"frame_to_frame", chained}, {"default", anchored}}) {
    ::testing::Test::RecordProperty(std::string(name) + "_pair_rms_rad", std::to_string(run.pair_rms));
    ::testing::Test::RecordProperty(std::string(name) + "_pose_rms_rad", std::to_string(run.pose_rms));
    ::testing::Test::RecordProperty(std::string(name) + "_worst_rad", std::to_string(run.worst));
  }
  EXPECT_EQ(chained.anchored, 0);
  EXPECT_GT(anchored.anchored, 50) << "a swing stays in reach of its first keyframe";
  EXPECT_LT(anchored.pair_rms, 1.05 * chained.pair_rms) << "each pair as exact as frame to frame";
  EXPECT_LT(anchored.pose_rms, chained.pose_rms) << "the chain held by its keyframe";
  EXPECT_LT(anchored.worst, chained.worst);
}

TEST(Odometry, TheKeyframeRegistrationIsMadeOnOneFrameInAnchorInterval) {
  Renderings scene;
  OdometryOptions frame_to_frame;
  frame_to_frame.keyframes.slots = 0;
  const SwingRun chained = runSwing(scene, frame_to_frame);
  OdometryOptions never;  // not within the swing's 60 frames
  never.keyframes.anchor_interval = 100;
  EXPECT_DOUBLE_EQ(runSwing(scene, never).pose_rms, chained.pose_rms)
      << "no keyframe registration: the poses are the pairs' chain";
  OdometryOptions third;
  third.keyframes.anchor_interval = 3;
  third.keyframes.anchor_gain = 0.3;
  const SwingRun sparse = runSwing(scene, third);
  ::testing::Test::RecordProperty("interval_3_pair_rms_rad", std::to_string(sparse.pair_rms));
  ::testing::Test::RecordProperty("interval_3_pose_rms_rad", std::to_string(sparse.pose_rms));
  EXPECT_LT(sparse.pair_rms, 1.05 * chained.pair_rms);
  EXPECT_LT(sparse.pose_rms, chained.pose_rms) << "the chain held by its keyframe";
}

/// A yaw turn of `step_deg` per frame for `frames` frames, with frames [gap_from, gap_to)
/// replaced by `bad` (an error) or left out (`bad` empty: an outage the caller reports).
struct GapRun {
  std::vector<OdometryResult> results;  ///< of the frames processed without error
  int errors = 0;
};

GapRun runTurnWithGap(Renderings& scene, double step_deg, int frames, int gap_from,
                      int gap_to, const cv::Mat& bad, const OdometryOptions& options = {}) {
  Odometry odometry(Calibration{}, options);
  GapRun run;
  bool gap = false;
  for (int k = 0; k < frames; ++k) {
    const double t = k / 30.0;
    if (k >= gap_from && k < gap_to) {
      if (bad.empty()) {
        gap = true;
        continue;
      }
      auto r = odometry.process(bad, {t, k});
      EXPECT_FALSE(r.has_value()) << "frame " << k;
      ++run.errors;
      continue;
    }
    auto r = odometry.process(scene.frame(attitude(0, 0, step_deg * k * kDeg), k), {t, k, gap});
    gap = false;
    EXPECT_TRUE(r.has_value()) << (r ? "" : r.error().c_str());
    if (r) run.results.push_back(*r);
  }
  return run;
}

void expectBridgedWithHeadingKept(const GapRun& run, double step_deg, int gap_from, int gap_to) {
  ASSERT_FALSE(run.results.empty());
  for (const OdometryResult& r : run.results) {
    SCOPED_TRACE(r.sequence);
    EXPECT_EQ(r.segment, 0) << "the gap did not start a new segment";
    if (r.sequence == gap_to) {
      EXPECT_EQ(r.state, TrackState::kBridged);
      EXPECT_EQ(r.reference_sequence, gap_from - 1);
      EXPECT_EQ(r.windows_reference_sequence, r.keyframe_sequence) << "found against the keyframe";
    } else if (r.sequence > 0) {
      EXPECT_EQ(r.state, TrackState::kTracked);
      EXPECT_EQ(r.windows_reference_sequence, r.reference_sequence) << "the pair's registration";
    }
    const Eigen::Isometry3d truth = attitude(0, 0, step_deg * static_cast<double>(r.sequence) * kDeg);
    EXPECT_LT(rotationError(r.pose, truth), 1e-3);
  }
  // The relative motion across the gap is the turn made during it.
  for (const OdometryResult& r : run.results) {
    if (r.sequence != gap_to) continue;
    EXPECT_NEAR(r.relative.estimate.omega.z(), step_deg * (gap_to - gap_from + 1) * kDeg, 1e-3);
  }
}

TEST(Odometry, OneCorruptFrameDuringATurnIsBridgedWithTheHeadingKept) {
  Renderings scene;
  const GapRun run = runTurnWithGap(scene, 2.0, 12, 6, 7, uniformFrame(0));
  EXPECT_EQ(run.errors, 1);
  expectBridgedWithHeadingKept(run, 2.0, 6, 7);
}

TEST(Odometry, TenCorruptFramesInARowAreBridged) {
  Renderings scene;
  const cv::Mat wrong_size(100, 100, CV_8UC1, cv::Scalar(90));
  const GapRun run = runTurnWithGap(scene, 2.0, 20, 5, 15, wrong_size, withKeyframes());
  EXPECT_EQ(run.errors, 10);
  expectBridgedWithHeadingKept(run, 2.0, 5, 15);
}

TEST(Odometry, ATwoSecondOutageDuringATurnIsBridgedByTheRingSearch) {
  Renderings scene;
  // 60 frames missing at 1.5 degrees per frame: 91.5 degrees turned across the gap, far
  // beyond any window's reach.
  const GapRun run = runTurnWithGap(scene, 1.5, 70, 5, 65, cv::Mat());
  expectBridgedWithHeadingKept(run, 1.5, 5, 65);
}

TEST(Odometry, AnUnrelatedViewAfterAGapStartsANewSegmentWithThePoseHeld) {
  TrackedTurn run;
  auto& [scene, odometry, turned, before] = run;
  ASSERT_EQ(before.state, TrackState::kTracked);
  // A lens cap: a blank view, nothing for the whole-ring search.
  const cv::Mat cap = uniformFrame(60);
  const OdometryResult lost = processOk(odometry, cap, 2 / 30.0, /*gap_before=*/true);
  EXPECT_EQ(lost.state, TrackState::kLost);
  EXPECT_EQ(lost.segment, 1);
  EXPECT_FALSE(lost.relative.has_motion);
  EXPECT_LT(rotationError(lost.pose, before.pose), 1e-12) << "the pose is held";
  // Nothing links the next view to a blank one either: another segment, the pose held.
  const OdometryResult next = processOk(odometry, scene.frame(turned, 3), 3 / 30.0);
  EXPECT_EQ(next.state, TrackState::kLost);
  EXPECT_EQ(next.segment, 2);
  EXPECT_LT(rotationError(next.pose, before.pose), 1e-12);
  // Then tracking goes on in that segment.
  const OdometryResult after = processOk(odometry, scene.frame(attitude(0, 0, 6 * kDeg), 4), 4 / 30.0);
  EXPECT_EQ(after.state, TrackState::kTracked);
  EXPECT_EQ(after.segment, 2);
  EXPECT_EQ(after.reference_sequence, 3);
}

TEST(Odometry, NoiseAfterATrackedFrameIsNotBelievedAndTheNextFrameGoesOnFromTheLastBelievedOne) {
  TrackedTurn run;
  auto& [scene, odometry, turned, before] = run;
  cv::Mat noise = uniformFrame(0);
  cv::randu(noise, 0, 255);
  const auto glitch = odometry.process(noise, {2 / 30.0});
  ASSERT_FALSE(glitch.has_value());
  EXPECT_EQ(glitch.error().code(), ErrorCode::kImplausible);
  const OdometryResult back = processOk(odometry, scene.frame(turned, 3), 3 / 30.0);
  EXPECT_EQ(back.segment, 0);
  EXPECT_EQ(back.reference_sequence, 1);
  EXPECT_LT(rotationError(back.pose, before.pose), 1e-3);
}

TEST(Odometry, TranslationAndTiltSwitchTheKeyframe) {
  {
    // 10 cm per frame in a 6 x 5 m room (|tau| about 0.04 > max_translation): every frame is
    // refined against the previous one, which becomes the keyframe.
    Renderings room(synth::SceneKind::kBox);
    Odometry odometry(Calibration{}, withKeyframes());
    for (int k = 0; k < 6; ++k) {
      Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
      pose.translation() = Eigen::Vector3d(0.1 * k, 0.0, 0.0);
      const OdometryResult r = processOk(odometry, room.frame(pose, k), k / 30.0);
      if (k > 0) {
        EXPECT_EQ(r.keyframe_sequence, k - 1) << k;
        EXPECT_EQ(r.frames_since_keyframe, 1);
      }
    }
  }
  {
    // Rolling 2 degrees per frame: the keyframe holds while the tilt from it is within
    // max_tilt_rad, then the frame becomes the keyframe.
    Renderings scene;
    OdometryOptions options = withKeyframes();
    options.keyframes.max_tilt_rad = 5 * kDeg;
    Odometry odometry(Calibration{}, options);
    std::vector<std::int64_t> keyframes;
    for (int k = 0; k < 8; ++k) {
      const OdometryResult r = processOk(odometry, scene.frame(attitude(2.0 * k * kDeg, 0, 0), k), k / 30.0);
      keyframes.push_back(r.keyframe_sequence);
      EXPECT_LT(rotationError(r.pose, attitude(2.0 * k * kDeg, 0, 0)), 5e-4) << k;
    }
    // Frames 1, 2 reach 4 degrees from frame 0; frame 3 (6 degrees) is refined against
    // frame 2 and becomes the keyframe; and so on.
    EXPECT_EQ(keyframes, (std::vector<std::int64_t>{0, 0, 0, 2, 3, 3, 5, 6}));
  }
}

TEST(Odometry, ChainedRotationsStayOrthonormalThroughManyKeyframeSwitches) {
  // Driving and turning in a room switches the keyframe every few frames; every pose is
  // composed from a keyframe's (K * (K^-1 * predicted)), so an orthogonality error must not
  // be carried from keyframe to keyframe (it grew to 5e-5 in 60 frames before).
  Renderings room(synth::SceneKind::kBox);
  Odometry odometry(Calibration{}, withKeyframes());
  double worst = 0.0;
  for (int k = 0; k < 60; ++k) {
    Eigen::Isometry3d pose = attitude(0.0, 0.0, 0.5 * k * kDeg);
    pose.translation() = Eigen::Vector3d(0.03 * k, 0.01 * k, 0.0);
    const OdometryResult r = processOk(odometry, room.frame(pose, k), k / 30.0);
    const Eigen::Matrix3d R = r.pose.linear();
    worst = std::max(worst, (R.transpose() * R - Eigen::Matrix3d::Identity()).norm());
  }
  ::testing::Test::RecordProperty("worst_orthogonality_error", std::to_string(worst));
  EXPECT_LT(worst, 1e-12);
}

TEST(Odometry, WithoutKeyframesEveryFrameIsRefinedAgainstThePreviousOne) {
  Renderings scene;
  OdometryOptions options;
  options.keyframes.slots = 0;
  Odometry odometry(Calibration{}, options);
  for (int k = 0; k < 5; ++k) {
    const OdometryResult r = processOk(odometry, scene.frame(Eigen::Isometry3d::Identity(), k), k / 30.0);
    if (k > 0) {
      EXPECT_EQ(r.keyframe_sequence, k - 1);
    }
  }
}

TEST(Odometry, BadOptionsAreListedByField) {
  OdometryOptions options;
  options.keyframes.slots = 17;
  options.keyframes.max_tilt_rad = -1;
  options.pipeline.refine_iterations = 9;
  const auto problems = Odometry::validate(Calibration{}, options);
  ASSERT_EQ(problems.size(), 3u);
  EXPECT_THAT(problems[0], HasSubstr("pipeline.refine_iterations"));
  EXPECT_THAT(problems[1], HasSubstr("keyframes.slots"));
  EXPECT_THAT(problems[2], HasSubstr("keyframes.max_tilt_rad"));
  EXPECT_THROW(Odometry(Calibration{}, options), std::invalid_argument);
}

TEST(Odometry, ProcessAllocatesNothingAfterWarmUpThroughKeyframesAndGaps) {
  if (!testing::AllocationCounter::available())
    GTEST_SKIP() << "sanitizer build: the sanitizer owns malloc, allocations are not counted";
  cv::setNumThreads(1);
  Renderings scene;
  std::vector<cv::Mat> frames;
  for (int k = 0; k < 6; ++k) frames.push_back(scene.frame(attitude(0.02 * k, 0, 0.05 * k), k));
  const cv::Mat wrong_size(100, 100, CV_8UC1, cv::Scalar(7));
  OdometryOptions options = withKeyframes();
  options.pipeline.threads = 2;
  Odometry odometry(Calibration{}, options);
  for (int k = 0; k < 6; ++k) ASSERT_TRUE(odometry.process(frames[k], {k / 30.0}).has_value());
  (void)odometry.process(wrong_size, {0.2});
  ASSERT_TRUE(odometry.process(frames[0], {0.25}).has_value());  // after the gap: warms that path

  testing::AllocationCounter counter;
  int ok = 0;
  for (int i = 0; i < 120; ++i) {
    const bool gap = i % 40 == 20;
    if (i % 40 == 10) (void)odometry.process(wrong_size, {i / 30.0});
    if (odometry.process(frames[(i * 5) % 6], {i / 30.0, -1, gap}).has_value()) ++ok;
  }
  const std::int64_t allocations = counter.stop();
  EXPECT_EQ(ok, 120);
  EXPECT_EQ(allocations, 0) << "heap allocations in 120 frames of Odometry::process";
}

TEST(Odometry, TheGyroPathAllocatesNothingThroughBadSamplesAndAFullBuffer) {
  if (!testing::AllocationCounter::available())
    GTEST_SKIP() << "sanitizer build: the sanitizer owns malloc, allocations are not counted";
  cv::setNumThreads(1);
  Renderings scene;
  std::vector<cv::Mat> frames;
  for (int k = 0; k < 6; ++k) frames.push_back(scene.frame(attitude(0.0, 0.0, 0.01 * k), k));
  Calibration calibration;
  calibration.sensor.readout_s = 0.02;
  // 0.3 rad/s over 20 ms blurs each row over 1 px: the blur's kernels are made every frame.
  calibration.sensor.exposure_s = 0.02;
  calibration.imu = ImuCalibration{};
  OdometryOptions options = withKeyframes();
  Odometry odometry(calibration, options);
  // 3 kHz: 12000 samples in the 4 s below, more than the 8192 kept.
  constexpr double kRate = 3000.0;
  std::vector<GyroSample> batch(100);
  double t_gyro = -0.1;
  const auto fill = [&](double until) {
    std::size_t n = 0;
    while (t_gyro <= until && n < batch.size()) {
      batch[n++] = {t_gyro, Eigen::Vector3d(0.0, 0.0, 0.3)};
      t_gyro += 1.0 / kRate;
    }
    return std::span<const GyroSample>(batch.data(), n);
  };
  for (int k = 0; k < 6; ++k) {
    while (t_gyro <= k / 30.0 + 0.04) odometry.addGyro(fill(k / 30.0 + 0.04));
    ASSERT_TRUE(odometry.process(frames[k], {k / 30.0}).has_value());
  }
  const GyroSample bad[] = {{0.0, Eigen::Vector3d(NAN, 0.0, 0.0)},
                            {0.0, Eigen::Vector3d(200.0, 0.0, 0.0)},
                            {0.0, Eigen::Vector3d::Zero()}};  // long before the last sample

  // Each frame states its own exposure (auto-exposure), the calibration's (NaN), none, the
  // longest there is room for, or one that is refused.
  const double stated[] = {NAN, 0.004, SensorTiming::kMaxExposureS, 0.0, -1.0};
  testing::AllocationCounter counter;
  int ok = 0;
  for (int i = 6; i < 126; ++i) {
    const double t = i / 30.0;
    while (t_gyro <= t + 0.08) odometry.addGyro(fill(t + 0.08));
    if (i % 40 == 0) odometry.addGyro(bad);
    const FrameStamp stamp{.time_s = t, .exposure_s = stated[i % 5]};
    if (odometry.process(frames[static_cast<std::size_t>(i % 6)], stamp).has_value()) ++ok;
  }
  const std::int64_t allocations = counter.stop();
  EXPECT_EQ(ok, 120);
  EXPECT_EQ(allocations, 0) << "heap allocations in 120 frames with the gyro";
  const GyroCounters c = odometry.gyroCounters();
  EXPECT_EQ(c.exposures_refused, 24);
  EXPECT_GT(c.frames_with_gyro, 100);
  EXPECT_EQ(c.not_finite, 3);
  EXPECT_EQ(c.too_fast, 3);
  EXPECT_EQ(c.out_of_order, 0);
  EXPECT_EQ(c.clock_restarts, 3);  // a stamp a second or more back: the clock started over
}

}  // namespace
}  // namespace omnipose
