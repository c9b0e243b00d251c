// People walking by do not turn the robot: a slow yaw turn among three people walking around
// the camera, rendered with the exact renderer (sensor noise, 8-bit frames), is estimated as
// well as the same turn without them when the refinement pass checks each window's pixels
// (PipelineOptions::moving_content) or the fit's ring consensus leaves out the windows no
// static scene explains (MotionFit::Options::ring_consensus), and measurably worse without
// both.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>

#include "omnipose/odometry.hpp"
#include "omnipose/pipeline.hpp"
#include "omnipose/synth/synth.hpp"
#include "render_fixture.hpp"
#include "test_figures.hpp"

namespace omnipose {
namespace {

constexpr int kFrames = 13;
constexpr double kFrameInterval = 1.0 / 30.0;

/// Frame k of `renderer` along the slow turn at k / 30 s, with sensor noise.
cv::Mat noisyFrame(const synth::Renderer& renderer, int k, cv::RNG& rng) {
  return testing::noisyFrame(renderer, testing::slowTurnPose(k), k * kFrameInterval, rng);
}

/// RMS rotation error angle (rad) of the pipeline over the sequence rendered by `renderer`
/// (frame k at time k / 30 s on the walkers' clock, sensor noise of 3 grey levels), with the
/// refinement pass's pixel check and the fit's ring consensus on or off.
double rmsError(const synth::Renderer& renderer, bool moving_content, bool ring_consensus) {
  PipelineOptions options;
  options.moving_content = moving_content;
  options.fit.ring_consensus = ring_consensus;
  Pipeline pipeline(Calibration{}, options);
  cv::RNG rng(17);
  const auto attitude = [](int k) -> Eigen::Matrix3d { return testing::slowTurnPose(k).linear(); };
  const auto frame = [&](int k) { return noisyFrame(renderer, k, rng); };
  return testing::rmsRotationError(pipeline, kFrames, frame, attitude);
}

/// Over frames 1..3 of the turn: the mean fit weight (OdometryResult::window_weights) of the
/// windows judged moving (moving_fraction from 0.06 on, MovingContentCheck::kDropFraction:
/// left out of the fit), of those judged still (below 0.01, kKeepFraction: whole
/// confidence), and how many were judged moving.
struct MovingWeights {
  double moving = 0.0, still = 0.0;
  int moving_windows = 0;
};
MovingWeights movingWeights(const synth::Renderer& renderer) {
  Odometry odometry(Calibration{}, OdometryOptions{});
  cv::RNG rng(23);
  MovingWeights m;
  int still_windows = 0;
  for (int k = 0; k < 4; ++k) {
    const auto r = odometry.process(noisyFrame(renderer, k, rng), {k * kFrameInterval, k, false});
    EXPECT_TRUE(r.has_value());
    if (!r || k == 0) continue;
    EXPECT_EQ(r->window_weights.size(), r->windows.size());
    for (std::size_t i = 0; i < r->windows.size() && i < r->window_weights.size(); ++i) {
      const double f = r->windows[i].moving_fraction, w = r->window_weights[i];
      EXPECT_GE(w, 0.0);
      EXPECT_LE(w, 1.0);
      if (f >= 0.06) {
        m.moving += w;
        ++m.moving_windows;
      } else if (f < 0.01) {
        m.still += w;
        ++still_windows;
      }
    }
  }
  if (m.moving_windows > 0) m.moving /= m.moving_windows;
  if (still_windows > 0) m.still /= still_windows;
  return m;
}

TEST(Walkers, TheWindowsJudgedMovingWeighLessAndTheResultSaysWhich) {
  if (!std::filesystem::exists(testing::indoorPhoto())) GTEST_SKIP() << "missing photo";
  synth::Scene scene = synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kSphere);
  const MovingWeights twin = movingWeights(synth::Renderer(scene, Calibration{}));
  scene.walkers = synth::parseWalkers("3,0.5,1.8,1.2");
  scene.walkers.min_distance_m = 1.2;
  scene.walkers.max_distance_m = 1.6;
  scene.walkers.seed = 5;
  const MovingWeights people = movingWeights(synth::Renderer(scene, Calibration{}));
  // Three people of 18 to 24 deg each cover some of the 55 windows of every frame.
  EXPECT_GE(people.moving_windows, 6);
  EXPECT_EQ(people.moving, 0.0) << "a window judged moving is left out of the fit";
  EXPECT_GT(people.still, 0.5);
  // Nothing moves in the twin. Its windows at 110-116 deg (peaks 0.6 of the ring's median)
  // measure du 0.2-0.4 px off the ring in some frames; turning in place, where the ring agrees
  // within 0.02 px, the ring consensus leaves such a window out, and with it a neighbour that
  // the same weak region pulls part of the way (ring_consensus.hpp): at most 6 of the 165
  // windows of three frames.
  EXPECT_LE(twin.moving_windows, 6) << "nothing moves in the twin";
}

/// Over frames 1..3 of the turn, with the pixel check off and the ring consensus on or off:
/// how many windows were reported moving as a whole (moving_fraction 1), and their largest
/// fit weight.
struct JudgedWhole {
  int windows = 0;
  double largest_weight = 0.0;
};
JudgedWhole judgedWhole(const synth::Renderer& renderer, bool ring_consensus) {
  OdometryOptions options;
  options.pipeline.moving_content = false;
  options.pipeline.fit.ring_consensus = ring_consensus;
  Odometry odometry(Calibration{}, options);
  cv::RNG rng(29);
  JudgedWhole j;
  for (int k = 0; k < 4; ++k) {
    const auto r = odometry.process(noisyFrame(renderer, k, rng), {k * kFrameInterval, k, false});
    EXPECT_TRUE(r.has_value());
    if (!r || k == 0) continue;
    for (std::size_t i = 0; i < r->windows.size() && i < r->window_weights.size(); ++i) {
      const double f = r->windows[i].moving_fraction;
      EXPECT_TRUE(f == 0.0 || f == 1.0) << "only the consensus judges with the check off";
      if (f == 1.0) {
        ++j.windows;
        j.largest_weight = std::max(j.largest_weight, r->window_weights[i]);
      }
    }
  }
  return j;
}

// The windows the ring consensus leaves out are in the result, as the pixel check's are: five
// people covering a third of the ring around a slow turn.
TEST(Walkers, TheWindowsTheRingConsensusLeftOutAreReportedMoving) {
  if (!std::filesystem::exists(testing::indoorPhoto())) GTEST_SKIP() << "missing photo";
  synth::Scene scene = synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kSphere);
  const JudgedWhole twin = judgedWhole(synth::Renderer(scene, Calibration{}), true);
  scene.walkers = synth::parseWalkers("5,0.6,1.8,1.2");
  scene.walkers.min_distance_m = 1.2;
  scene.walkers.max_distance_m = 1.6;
  scene.walkers.seed = 5;
  const synth::Renderer people(scene, Calibration{});
  const JudgedWhole with = judgedWhole(people, true), without = judgedWhole(people, false);
  EXPECT_GE(with.windows, 6);
  EXPECT_EQ(with.largest_weight, 0.0) << "a window the consensus judged is out of the fit";
  EXPECT_EQ(without.windows, 0);
  EXPECT_LE(twin.windows, 6) << "nothing moves in the twin (windows of weak peak, above)";
}

TEST(Walkers, PeopleWalkingAroundTheCameraDoNotMoveTheEstimate) {
  if (!std::filesystem::exists(testing::indoorPhoto())) GTEST_SKIP() << "missing photo";
  synth::Scene scene = synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kSphere);
  const synth::Renderer twin(scene, Calibration{});
  // Three people 0.5 m wide and 1.8 m tall walking at 1.2 m/s on circles of 1.2 to 1.6 m
  // around the camera (18 to 24 deg of the ring each), as the real-camera benchmark's.
  scene.walkers = synth::parseWalkers("3,0.5,1.8,1.2");
  scene.walkers.min_distance_m = 1.2;
  scene.walkers.max_distance_m = 1.6;
  scene.walkers.seed = 5;
  const synth::Renderer with_walkers(scene, Calibration{});
  const double plain =
      testing::recordFigure("twin_rms_rad", rmsError(twin, true, true), 9);
  const double checked =
      testing::recordFigure("walkers_rms_rad", rmsError(with_walkers, true, true), 9);
  const double unchecked = testing::recordFigure(
      "walkers_unchecked_rms_rad", rmsError(with_walkers, false, false), 9);
  const double check_alone = testing::recordFigure(
      "walkers_pixel_check_alone_rms_rad", rmsError(with_walkers, true, false), 9);
  const double consensus_alone = testing::recordFigure(
      "walkers_ring_consensus_alone_rms_rad", rmsError(with_walkers, false, true), 9);
  ASSERT_GT(plain, 0.0);
  // Without either the people's windows turn the robot with them (yaw biased every pair:
  // 5.9 times the twin's error when this was written, 3.5 times since the plane depth prior
  // is the default); with them their windows are left out (1.6 times the twin: what is left
  // is mostly the tilt that a third fewer windows on one side of the ring determine less
  // well, on this photo's faint walls; 1.1 times on the real-camera benchmark's park photo,
  // docs/results/REAL_CAMERA.md). Each of the two holds these people alone (1.7-1.9 times).
  EXPECT_LT(checked, 2.0 * plain) << "twin " << plain << " rad, walkers " << checked;
  EXPECT_GT(unchecked, 1.5 * checked) << "checked " << checked << " rad, unchecked " << unchecked;
  EXPECT_GT(unchecked, 1.5 * check_alone) << "the pixel check alone " << check_alone << " rad";
  EXPECT_GT(unchecked, 1.5 * consensus_alone)
      << "the ring consensus alone " << consensus_alone << " rad";
  // A sequence without anything moving is the same with and without them, to the noise: no
  // window of the twin is discounted enough to matter.
  const double plain_unchecked = rmsError(twin, false, false);
  EXPECT_NEAR(plain, plain_unchecked, 0.05 * plain_unchecked);
}

}  // namespace
}  // namespace omnipose
