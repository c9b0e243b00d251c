// Loop closure (src/pipeline/loop_closure.hpp, OdometryResult::map_pose) against the exact
// renderer. Driving a rectangle and back to its start closes a loop: the map pose's heading
// comes back to the truth while the odometry's pose, continuous, is the same as without a
// map. Matches that would be wrong are refused: a look-alike far from where the odometry
// says the robot is (two identical rooms), a match that needs a larger turn of the map
// than the odometry can have drifted (a symmetric room), a view that is not the place.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "allocation_counter.hpp"
#include "map/map_file.hpp"
#include "omnipose/odometry.hpp"
#include "omnipose/so3.hpp"
#include "omnipose/synth/synth.hpp"
#include "pipeline/frame_registrar.hpp"
#include "pipeline/loop_closure.hpp"
#include "planar_pose.hpp"
#include "render_fixture.hpp"

namespace omnipose {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

using testing::planarPose;

double yawOf(const Eigen::Isometry3d& T) { return std::atan2(T(1, 0), T(0, 0)); }
double wrapAngle(double a) { return std::remainder(a, 2.0 * std::numbers::pi); }

cv::Mat noisy(const cv::Mat& render, std::uint64_t seed) {
  synth::DegradeOptions noise;
  noise.noise_sigma = 2.0;
  return synth::degrade(render, noise, seed);
}

/// LoopClosure fed frames of a sphere scene (every position looks the same, so the
/// odometry's word decides where a frame is) at odometry poses the test chooses.
class MapOfSphereViews : public ::testing::Test {
 protected:
  MapOfSphereViews()
      : renderer_(synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kSphere),
                  Calibration{}, {synth::OutputKind::kOmni, 2}),
        registrar_(Calibration{}, PipelineOptions{}, 2),
        loop_(LoopClosureOptions{}, registrar_, 1, 0.03) {}

  /// The frame whose true heading is `true_yaw` at odometry pose `odometry`.
  pipeline::LoopClosure::Update feed(double true_yaw, const Eigen::Isometry3d& odometry) {
    const cv::Mat frame = noisy(renderer_.render(planarPose(0, 0, true_yaw)), ++seed_);
    EXPECT_TRUE(registrar_.unwrap(frame).has_value());
    if (!registrar_.hasPrevious()) registrar_.makeCurrentPrevious();
    pipeline::LoopClosure::Frame f;
    f.sequence = static_cast<std::int64_t>(seed_);
    f.time_s = static_cast<double>(seed_) / 30.0;
    f.odometry = odometry;
    return loop_.update(f);
  }
  /// Places at the origin and along +x every 0.12 scene distances (6 of them), the views
  /// all at heading 0 and the odometry without drift.
  void driveOut() {
    feed(0.0, planarPose(0, 0, 0));
    for (int k = 1; k <= 6; ++k) feed(0.0, planarPose(0.12 * k, 0, 0));
    ASSERT_EQ(loop_.places(), 7);
  }
  /// `frames` frames of heading `true_yaw` at odometry pose `odometry`; the closures.
  int closuresOver(int frames, double true_yaw, const Eigen::Isometry3d& odometry,
                   pipeline::LoopClosure::Update* last = nullptr) {
    int closed = 0;
    for (int k = 0; k < frames; ++k) {
      const auto u = feed(true_yaw, odometry);
      closed += u.loop_closed ? 1 : 0;
      if (last != nullptr) *last = u;
    }
    return closed;
  }

  synth::Renderer renderer_;
  pipeline::FrameRegistrar registrar_;
  pipeline::LoopClosure loop_;
  std::uint64_t seed_ = 0;
};

TEST_F(MapOfSphereViews, BackAtTheStartWithAHeadingDriftClosesTheLoop) {
  driveOut();
  // Back near the start, the odometry's heading 2 degrees off.
  pipeline::LoopClosure::Update last;
  const int closed = closuresOver(14, 0.0, planarPose(0.01, 0, 2.0 * kDeg), &last);
  EXPECT_GE(closed, 1);
  ::testing::Test::RecordProperty("map_yaw_error_rad", std::to_string(yawOf(last.map_pose)));
  EXPECT_NEAR(yawOf(last.map_pose), 0.0, 0.05 * kDeg) << "the map's heading is the truth's";
  EXPECT_NEAR(yawOf(last.correction), -2.0 * kDeg, 0.05 * kDeg);
  // The counters say what happened: every closure verified, none refused by the gates.
  const LoopClosureCounters& c = loop_.counters();
  EXPECT_EQ(c.closures, closed);
  EXPECT_GE(c.verified, c.closures * LoopClosureOptions{}.confirmations);
  EXPECT_EQ(c.compared, c.verified + c.no_ring_peak + c.turned_too_far + c.fit_failed + c.too_far);
  EXPECT_EQ(c.turned_too_far, 0);
  EXPECT_EQ(c.disagreed, 0);
}

TEST_F(MapOfSphereViews, ALookAlikeFarFromWhereTheOdometryIsDoesNotCloseALoop) {
  driveOut();
  // The same view (an identical room) 2 scene distances on: nothing within search_radius.
  EXPECT_EQ(closuresOver(20, 0.0, planarPose(2.0, 0, 2.0 * kDeg)), 0);
}

TEST_F(MapOfSphereViews, AMatchNeedingALargerTurnThanTheDriftCanBeIsRefused) {
  driveOut();
  // The view turned 30 degrees from where the odometry faces (a symmetric room's other
  // half, or a wrong match): beyond max_correction_rad.
  pipeline::LoopClosure::Update last;
  EXPECT_EQ(closuresOver(20, 30.0 * kDeg, planarPose(0.01, 0, 0.0), &last), 0);
  EXPECT_TRUE(last.correction.isApprox(Eigen::Isometry3d::Identity()));
}

TEST_F(MapOfSphereViews, AViewThatIsNotThePlaceDoesNotCloseALoop) {
  driveOut();
  // Something else entirely in front of the camera (the photo upside down: the same
  // texture, a different place).
  int closed = 0;
  for (int k = 0; k < 20; ++k) {
    cv::Mat frame = noisy(renderer_.render(planarPose(0, 0, 0)), ++seed_);
    cv::flip(frame, frame, 0);
    ASSERT_TRUE(registrar_.unwrap(frame).has_value());
    pipeline::LoopClosure::Frame f;
    f.sequence = static_cast<std::int64_t>(seed_);
    f.odometry = planarPose(0.01, 0, 0.5 * kDeg);
    closed += loop_.update(f).loop_closed ? 1 : 0;
  }
  EXPECT_EQ(closed, 0);
}

TEST_F(MapOfSphereViews, ComparingAndClosingAllocatesNothing) {
  if (!testing::AllocationCounter::available())
    GTEST_SKIP() << "sanitizer build: the sanitizer owns malloc, allocations are not counted";
  cv::setNumThreads(1);
  driveOut();
  std::vector<cv::Mat> frames;
  for (int k = 0; k < 3; ++k) frames.push_back(noisy(renderer_.render(planarPose(0, 0, 0)), 100 + k));
  const auto step = [&](int k, double drift) {
    EXPECT_TRUE(registrar_.unwrap(frames[static_cast<std::size_t>(k % 3)]).has_value());
    pipeline::LoopClosure::Frame f;
    f.sequence = 1000 + k;
    f.odometry = planarPose(0.01, 0, drift);
    return loop_.update(f).loop_closed;
  };
  for (int k = 0; k < 14; ++k) step(k, 1.0 * kDeg);  // warm up: a closure
  testing::AllocationCounter counter;
  int closed = 0;
  for (int k = 0; k < 30; ++k) closed += step(k, (1.0 + 0.1 * (k / 10)) * kDeg) ? 1 : 0;
  EXPECT_EQ(counter.stop(), 0);
  EXPECT_GE(closed, 1);
}

TEST_F(MapOfSphereViews, ALoadedMapOfLookAlikesIsNeverAnchoredAndIsDroppedOnceTheRobotMoved) {
  driveOut();
  map::MapSnapshot saved;
  loop_.snapshot(saved);
  ASSERT_EQ(saved.place_count, 7);
  // Every place of a sphere looks the same from everywhere: two places match a frame and
  // disagree on where the map puts it, so no frame anchors the loaded map.
  LoopClosureOptions options;
  options.check_interval = 1;
  pipeline::LoopClosure restarted(options, registrar_, 1, 0.03);
  ASSERT_TRUE(restarted.restore(saved).has_value());
  EXPECT_TRUE(restarted.relocalising());
  EXPECT_EQ(restarted.places(), 7);
  std::vector<cv::Mat> frames;
  for (int k = 0; k < 3; ++k) frames.push_back(noisy(renderer_.render(planarPose(0, 0, 0.3)), 40 + k));
  int closed = 0, checks_relocalising = 0;
  for (int k = 0; k < pipeline::LoopClosure::kRelocaliseChecks + 5; ++k) {
    ASSERT_TRUE(registrar_.unwrap(frames[static_cast<std::size_t>(k % 3)]).has_value());
    pipeline::LoopClosure::Frame f;
    f.sequence = 100 + k;
    // The robot drives 0.4 scene distances (more than search_radius) along y.
    f.odometry = planarPose(0, 0.004 * k, 0);
    const auto u = restarted.update(f);
    closed += u.loop_closed ? 1 : 0;
    if (restarted.relocalising()) {
      ++checks_relocalising;
      EXPECT_TRUE(u.map_pose.isApprox(f.odometry)) << k;
      EXPECT_EQ(restarted.places(), 7) << "no places while the map is not found";
    }
  }
  EXPECT_EQ(closed, 0);
  EXPECT_GE(restarted.counters().disagreed, 1) << "two places that disagree on the map";
  EXPECT_EQ(restarted.counters().closures, 0);
  EXPECT_EQ(checks_relocalising, pipeline::LoopClosure::kRelocaliseChecks - 1);
  EXPECT_FALSE(restarted.relocalising()) << "dropped";
  EXPECT_EQ(restarted.places(), 1) << "a new map, begun where the old one was dropped";
}

/// A rectangle of 1.2 x 0.8 m (`short_side` frames of 3 cm: 27) in the box room at 3 cm per
/// frame with 90-degree left turns in place at 6 degrees per frame, `laps` times, then
/// `extra` frames along the first side; it starts at `start`, facing as it does.
std::vector<Eigen::Isometry3d> rectangle(
    int laps, int extra, int short_side = 27,
    const Eigen::Isometry3d& start = Eigen::Isometry3d::Identity()) {
  std::vector<Eigen::Isometry3d> truth{start};
  const auto go = [&](int frames, double step_m) {
    for (int k = 0; k < frames; ++k) {
      Eigen::Isometry3d T = truth.back();
      T.translation() += T.linear() * Eigen::Vector3d(step_m, 0, 0);
      truth.push_back(T);
    }
  };
  const auto turn = [&] {
    for (int k = 0; k < 15; ++k) truth.push_back(truth.back() * planarPose(0, 0, 6.0 * kDeg));
  };
  for (int lap = 0; lap < laps; ++lap) {
    for (int side = 0; side < 4; ++side) {
      go(side % 2 == 0 ? 40 : short_side, 0.03);
      turn();
    }
  }
  go(extra, 0.03);
  return truth;
}

struct RectangleRun {
  std::vector<OdometryResult> results;
  std::vector<Eigen::Isometry3d> truth;
};

/// The frames of rectangle(1, 12), rendered once for the tests that drive it.
const std::vector<cv::Mat>& rectangleFrames() {
  static const std::vector<cv::Mat> frames = [] {
    const synth::Renderer renderer(
        synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kBox), Calibration{},
        {synth::OutputKind::kOmni, 1});
    std::vector<cv::Mat> out;
    const std::vector<Eigen::Isometry3d> truth = rectangle(1, 12);
    for (std::size_t k = 0; k < truth.size(); ++k)
      out.push_back(noisy(renderer.render(truth[k]), k + 1));
    return out;
  }();
  return frames;
}

RectangleRun driveRectangle(const OdometryOptions& options) {
  RectangleRun run;
  run.truth = rectangle(1, 12);
  const std::vector<cv::Mat>& frames = rectangleFrames();
  Odometry odometry(Calibration{}, options);
  for (std::size_t k = 0; k < run.truth.size(); ++k) {
    auto r = odometry.process(frames[k], {k / 30.0});
    EXPECT_TRUE(r.has_value()) << k << ": " << (r ? "" : r.error().c_str());
    if (!r) return run;
    run.results.push_back(*r);
  }
  return run;
}

TEST(LoopClosure, DrivingBackToTheStartBringsTheMapHeadingBack) {
  OdometryOptions without;
  without.loop_closure.enabled = false;
  const RectangleRun odometry_only = driveRectangle(without);
  const RectangleRun mapped = driveRectangle(OdometryOptions{});
  ASSERT_EQ(mapped.results.size(), mapped.truth.size());
  ASSERT_EQ(odometry_only.results.size(), mapped.truth.size());
  int closures = 0, first_closure = -1;
  double jump_without_closure = 0.0;
  for (std::size_t k = 0; k < mapped.results.size(); ++k) {
    const OdometryResult& r = mapped.results[k];
    EXPECT_TRUE(r.pose.isApprox(odometry_only.results[k].pose, 1e-9))
        << k << ": the odometry's pose is the same with and without the map";
    if (r.loop_closed) {
      ++closures;
      if (first_closure < 0) first_closure = static_cast<int>(k);
    } else if (k > 0) {
      // Without a closure the map pose moves as the odometry's pose does.
      const Eigen::Isometry3d d_map = mapped.results[k - 1].map_pose.inverse() * r.map_pose;
      const Eigen::Isometry3d d_odom = mapped.results[k - 1].pose.inverse() * r.pose;
      jump_without_closure = std::max(
          jump_without_closure, rotationVector(d_map.linear().transpose() * d_odom.linear()).norm());
    }
  }
  const std::size_t end = mapped.results.size() - 1;
  const double odometry_error =
      rotationVector(mapped.results[end].pose.linear().transpose() * mapped.truth[end].linear()).norm();
  const double map_error =
      rotationVector(mapped.results[end].map_pose.linear().transpose() * mapped.truth[end].linear()).norm();
  ::testing::Test::RecordProperty("closures", closures);
  ::testing::Test::RecordProperty("first_closure_frame", first_closure);
  ::testing::Test::RecordProperty("odometry_heading_error_rad", std::to_string(odometry_error));
  ::testing::Test::RecordProperty("map_heading_error_rad", std::to_string(map_error));
  EXPECT_GE(closures, 1);
  EXPECT_GT(first_closure, 190) << "no closure before the robot is back at the start";
  EXPECT_LT(jump_without_closure, 1e-9);
  EXPECT_LT(map_error, 0.1 * kDeg);
  EXPECT_GT(mapped.results[end].places, 10);
}

// Whole scenes built to fool the map: each frame rendered from the exact renderer, so what a
// closure matched can be told from the truth. A closure is wrong when the place it matched
// was made more than search_radius (0.3 scene distances, about 0.75 m in this room) from
// where the frame truly is, or when it turns the map pose's heading away from the truth.

/// A run of Odometry with the default options over rendered frames, and what its closures
/// matched (auditClosures(), which also records it as the test's properties).
struct ClosureAudit {
  int frames = 0;       ///< processed without error
  int closures = 0;
  int wrong_place = 0;  ///< closures whose place was truly more than 0.75 m away
  double worst_place_distance_m = 0.0;  ///< over the closures
  /// Over the closure frames: the map pose's rotation error against the truth, radians.
  double worst_closure_rotation_error_rad = 0.0;
  double end_map_rotation_error_rad = 0.0;  ///< at the last frame
  LoopClosureCounters map;                  ///< the odometry's, at the end
};

/// Rotation between a frame's estimated pose and its true one, both from the first frame.
double rotationError(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& truth0,
                     const Eigen::Isometry3d& truth) {
  return rotationVector(estimate.linear().transpose() * (truth0.inverse() * truth).linear()).norm();
}

/// Records the audit's figures as the test's properties (--gtest_output).
void recordAudit(const ClosureAudit& audit) {
  ::testing::Test::RecordProperty("closures", audit.closures);
  ::testing::Test::RecordProperty("worst_place_distance_m",
                                  std::to_string(audit.worst_place_distance_m));
  ::testing::Test::RecordProperty("worst_closure_rotation_error_rad",
                                  std::to_string(audit.worst_closure_rotation_error_rad));
  ::testing::Test::RecordProperty("end_map_rotation_error_rad",
                                  std::to_string(audit.end_map_rotation_error_rad));
  const LoopClosureCounters& m = audit.map;
  for (const auto& [name, value] :
       {std::pair{"compared", m.compared}, {"no_ring_peak", m.no_ring_peak},
        {"turned_too_far", m.turned_too_far}, {"fit_failed", m.fit_failed},
        {"too_far", m.too_far}, {"verified", m.verified}, {"map_closures", m.closures}})
    ::testing::Test::RecordProperty(name, std::to_string(value));
}

ClosureAudit auditClosures(const std::vector<cv::Mat>& frames,
                           const std::vector<Eigen::Isometry3d>& truth) {
  ClosureAudit audit;
  Odometry odometry(Calibration{}, OdometryOptions{});
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const auto r = odometry.process(frames[k], {k / 30.0, static_cast<std::int64_t>(k)});
    if (!r) continue;  // a glitch the odometry refused (the cut between two rooms)
    ++audit.frames;
    audit.end_map_rotation_error_rad = rotationError(r->map_pose, truth[0], truth[k]);
    if (!r->loop_closed) continue;
    ++audit.closures;
    const auto place = static_cast<std::size_t>(r->loop_place_sequence);
    const double distance = (truth[k].translation() - truth.at(place).translation()).norm();
    audit.worst_place_distance_m = std::max(audit.worst_place_distance_m, distance);
    audit.wrong_place += distance > 0.75 ? 1 : 0;
    audit.worst_closure_rotation_error_rad =
        std::max(audit.worst_closure_rotation_error_rad, audit.end_map_rotation_error_rad);
  }
  audit.map = odometry.loopClosureCounters();
  recordAudit(audit);
  return audit;
}

/// The indoor photo's box room made point-symmetric about its centre: the photo's first half
/// of azimuths repeated in the second, so the view from (x, y) facing psi is the view from
/// (-x, -y) facing psi + 180 deg.
synth::Scene symmetricRoom() {
  synth::Scene scene = synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kBox);
  const int half = scene.texture.cols / 2;
  scene.texture(cv::Rect(0, 0, half, scene.texture.rows))
      .copyTo(scene.texture(cv::Rect(half, 0, half, scene.texture.rows)));
  return scene;
}

TEST(LookAlikeScenes, TheOtherHalfOfASymmetricRoomNeverClosesALoop) {
  // One lap of a 1.2 x 0.4 m rectangle centred on the room, then back along the first side:
  // on the third side the robot sees, 0.4-0.75 m from it, the first side's places exactly as
  // they were made, turned by 180 degrees in the map. Only the start is a true revisit.
  const synth::Renderer renderer(symmetricRoom(), Calibration{}, {synth::OutputKind::kOmni, 1});
  const std::vector<Eigen::Isometry3d> truth =
      rectangle(1, 20, 13, Eigen::Isometry3d(Eigen::Translation3d(-0.6, -0.2, 0.0)));
  // The trap is real: the third side's frame is the first side's, turned.
  const Eigen::Isometry3d mirror = planarPose(0, 0, std::numbers::pi);
  const cv::Mat first = renderer.render(truth[10]);
  const cv::Mat third = renderer.render(mirror * truth[10]);
  EXPECT_LT(cv::norm(first, third, cv::NORM_L1) / static_cast<double>(first.total()), 1.0)
      << "mean grey-level difference";
  std::vector<cv::Mat> frames;
  for (std::size_t k = 0; k < truth.size(); ++k)
    frames.push_back(noisy(renderer.render(truth[k]), 900 + k));
  const ClosureAudit audit = auditClosures(frames, truth);
  EXPECT_EQ(audit.frames, static_cast<int>(truth.size()));
  EXPECT_GE(audit.map.turned_too_far, 1) << "a place registered and refused for its heading";
  EXPECT_EQ(audit.wrong_place, 0) << "worst " << audit.worst_place_distance_m << " m";
  EXPECT_LT(audit.worst_closure_rotation_error_rad, 0.5 * kDeg);
  EXPECT_LT(audit.end_map_rotation_error_rad, 1.0 * kDeg);
}

TEST(LookAlikeScenes, ARoomLikeTheFirstBeyondADoorIsNotTakenForIt) {
  // The robot drives 1.5 m along the room's x axis, then through a door (a cut in the
  // frames: the odometry cannot follow it) into a second room exactly like the first, 1.5 m
  // further along x, where it drives the first stretch again: every view of the second
  // room is one the map holds, 1.5 m (0.6 scene distances) from where the robot is.
  constexpr double kRoomOffset = 1.5;
  constexpr int kStretch = 50;  // frames of 3 cm in each room
  const synth::Renderer renderer(
      synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kBox), Calibration{},
      {synth::OutputKind::kOmni, 1});
  std::vector<Eigen::Isometry3d> truth;
  std::vector<cv::Mat> frames;
  for (int k = 0; k < 2 * kStretch; ++k) {
    truth.push_back(planarPose(-0.75 + 0.03 * k, 0.1, 0.0));
    const double in_room = k < kStretch ? 0.0 : kRoomOffset;
    const Eigen::Isometry3d seen = Eigen::Translation3d(-in_room, 0, 0) * truth.back();
    frames.push_back(noisy(renderer.render(seen), 1200 + static_cast<std::uint64_t>(k)));
  }
  const ClosureAudit audit = auditClosures(frames, truth);
  // The odometry refuses a few frames after the cut as glitches, then takes up the chain.
  EXPECT_GE(audit.frames, 2 * kStretch - 10);
  EXPECT_EQ(audit.closures, 0) << "the robot never came back to a place";
}

TEST(LookAlikeScenes, PeopleInFrontOfTheCameraAtTheStartNeverCloseALoopWrongly) {
  // The rectangle's lap, centred on the room, then back along its first side with three
  // people 0.6 m wide walking around the room's centre 1.1-1.4 m from it (0.4-1 m from the
  // camera), in both directions: the frames that come back to the first places have people
  // in front of the camera that the places do not.
  const std::vector<Eigen::Isometry3d> truth =
      rectangle(1, 20, 27, Eigen::Isometry3d(Eigen::Translation3d(-0.6, -0.4, 0.0)));
  const std::size_t back = truth.size() - 21;  // the first frame back at the start
  const synth::Renderer empty(synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kBox),
                              Calibration{}, {synth::OutputKind::kOmni, 1});
  synth::Scene scene = synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kBox);
  scene.walkers.count = 3;
  scene.walkers.width_m = 0.6;
  scene.walkers.min_distance_m = 1.1;
  scene.walkers.max_distance_m = 1.4;
  scene.walkers.speed_m_s = 0.8;
  scene.walkers.seed = 54;
  const synth::Renderer people(std::move(scene), Calibration{}, {synth::OutputKind::kOmni, 1});
  std::vector<cv::Mat> frames;
  for (std::size_t k = 0; k < truth.size(); ++k)
    frames.push_back(noisy(k < back ? empty.render(truth[k]) : people.render(truth[k], k / 30.0),
                           1500 + k));
  const ClosureAudit audit = auditClosures(frames, truth);
  EXPECT_EQ(audit.frames, static_cast<int>(truth.size()));
  EXPECT_GE(audit.map.compared, 1) << "frames with people were compared with the places";
  EXPECT_EQ(audit.wrong_place, 0) << "worst " << audit.worst_place_distance_m << " m";
  EXPECT_LT(audit.worst_closure_rotation_error_rad, 0.5 * kDeg);
}

/// The rectangle's first side, turn and second side (rendered once, like rectangleFrames()).
constexpr std::size_t kTwoSides = 85;
const std::vector<cv::Mat>& twoSidesFrames() {
  static const std::vector<cv::Mat> frames = [] {
    const synth::Renderer renderer(
        synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kBox), Calibration{},
        {synth::OutputKind::kOmni, 1});
    std::vector<cv::Mat> out;
    const std::vector<Eigen::Isometry3d> truth = rectangle(1, 0);
    for (std::size_t k = 0; k < kTwoSides; ++k) out.push_back(noisy(renderer.render(truth[k]), k + 1));
    return out;
  }();
  return frames;
}

/// The map of twoSidesFrames(), as saved at its end.
const map::MapSnapshot& savedRectangleMap() {
  static const map::MapSnapshot saved = [] {
    Odometry odometry(Calibration{}, OdometryOptions{});
    const std::vector<cv::Mat>& frames = twoSidesFrames();
    for (std::size_t k = 0; k < frames.size(); ++k)
      EXPECT_TRUE(odometry.process(frames[k], {k / 30.0}).has_value());
    map::MapSnapshot snapshot;
    EXPECT_TRUE(odometry.snapshotMap(snapshot));
    return snapshot;
  }();
  return saved;
}

struct Restart {
  int first_closure = -1;  ///< the frame (from the restart) that found the map, -1 for none
  /// At that frame: the map pose's heading error, and that of the place matched as saved
  /// (the map's own error there, from the first run's drift and solve), radians.
  double heading_error_rad = 0.0;
  double place_heading_error_rad = 0.0;
  double place_distance_m = 0.0;  ///< between the frame's true position and the place's
  bool relocalising_until_closure = true;
  bool map_pose_was_odometry_until_closure = true;
};

/// A restart with the saved map at frame `from` of the rectangle: the odometry begins at the
/// identity there, up to `frames` frames on, until it finds the map.
Restart restartAt(std::size_t from, std::size_t frames) {
  const map::MapSnapshot& saved = savedRectangleMap();
  const std::vector<Eigen::Isometry3d> truth = rectangle(1, 12);
  const std::vector<cv::Mat>& images = twoSidesFrames();
  Odometry odometry(Calibration{}, OdometryOptions{});
  EXPECT_TRUE(odometry.restoreMap(saved).has_value());
  Restart out;
  for (std::size_t k = from; k < from + frames && k < images.size(); ++k) {
    auto r = odometry.process(images[k], {k / 30.0});
    EXPECT_TRUE(r.has_value()) << k;
    if (!r) break;
    if (!r->loop_closed) {
      out.relocalising_until_closure = out.relocalising_until_closure && r->relocalising;
      out.map_pose_was_odometry_until_closure =
          out.map_pose_was_odometry_until_closure && r->map_pose.isApprox(r->pose, 1e-12);
      continue;
    }
    out.first_closure = static_cast<int>(k - from);
    out.heading_error_rad = wrapAngle(yawOf(truth[k].inverse() * r->map_pose));
    // The places were numbered by their frames' index in the first run.
    const auto place = static_cast<std::size_t>(r->loop_place_sequence);
    for (int i = 0; i < saved.place_count; ++i) {
      const map::SavedPlace& p = saved.places[static_cast<std::size_t>(i)];
      if (p.sequence != r->loop_place_sequence) continue;
      out.place_heading_error_rad = wrapAngle(yawOf(truth[place].inverse() * p.pose));
    }
    out.place_distance_m = (truth[k].translation() - truth[place].translation()).norm();
    break;
  }
  return out;
}

TEST(LoopClosureRestart, ASavedMapFindsTheHeadingAgainAfterARestartInAKnownPlace) {
  const map::MapSnapshot& saved = savedRectangleMap();
  ASSERT_GE(saved.place_count, 5);
  // Restarted at the start of the second side, facing 90 degrees from where the map began.
  const Restart r = restartAt(58, 24);
  ::testing::Test::RecordProperty("first_closure_frame", r.first_closure);
  ::testing::Test::RecordProperty("heading_error_rad", std::to_string(r.heading_error_rad));
  ::testing::Test::RecordProperty("place_heading_error_rad",
                                  std::to_string(r.place_heading_error_rad));
  ASSERT_GE(r.first_closure, 0) << "the saved map was not recognised";
  EXPECT_LE(r.first_closure, 19) << "three checks six frames apart";
  EXPECT_TRUE(r.relocalising_until_closure);
  EXPECT_TRUE(r.map_pose_was_odometry_until_closure);
  EXPECT_LT(r.place_distance_m, 0.3) << "a place near the frame";
  // The heading is the map's at that place: its own error there and the match's.
  EXPECT_NEAR(r.heading_error_rad, r.place_heading_error_rad, 0.1 * kDeg);
  EXPECT_LT(std::abs(r.heading_error_rad), 0.3 * kDeg);
}

TEST(LoopClosureRestart, ARestartFarFromEveryPlaceIsNotTakenForOne) {
  // The saved map of the rectangle; the camera started in a room it has never seen, the
  // same room mirrored (the signature, a magnitude spectrum along the azimuth, cannot tell
  // a mirror image): no closure, the map pose stays the odometry's.
  synth::Scene mirrored = synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kBox);
  synth::turnTexture(mirrored, 0.0, true);
  const synth::Renderer renderer(std::move(mirrored), Calibration{}, {synth::OutputKind::kOmni, 1});
  Odometry odometry(Calibration{}, OdometryOptions{});
  ASSERT_TRUE(odometry.restoreMap(savedRectangleMap()).has_value());
  int closed = 0;
  for (int k = 0; k < 40; ++k) {
    const cv::Mat frame =
        noisy(renderer.render(planarPose(0.01 * k, 0, 0.5 * kDeg * k)), 500 + k);
    auto r = odometry.process(frame, {k / 30.0});
    ASSERT_TRUE(r.has_value());
    closed += r->loop_closed ? 1 : 0;
    EXPECT_TRUE(r->relocalising) << k;
    EXPECT_TRUE(r->map_pose.isApprox(r->pose, 1e-12)) << k;
  }
  EXPECT_EQ(closed, 0);
}

TEST(LoopClosureRestart, AMapOfAnotherPanoramaSizeIsRefusedAndLeavesNoMap) {
  const synth::Renderer renderer(
      synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kBox), Calibration{},
      {synth::OutputKind::kOmni, 1});
  std::vector<cv::Mat> frames;
  for (int k = 0; k < 3; ++k) frames.push_back(noisy(renderer.render(planarPose(0.03 * k, 0, 0)), 7 + k));
  map::MapSnapshot other;
  {
    Odometry first(Calibration{}, OdometryOptions{});
    for (std::size_t k = 0; k < 3; ++k) ASSERT_TRUE(first.process(frames[k], {k / 30.0}));
    ASSERT_TRUE(first.snapshotMap(other));
    ASSERT_EQ(other.place_count, 1);
  }
  other.panorama = cv::Size(other.panorama.width / 2, other.panorama.height);
  Odometry odometry(Calibration{}, OdometryOptions{});
  const auto restored = odometry.restoreMap(other);
  ASSERT_FALSE(restored.has_value());
  EXPECT_EQ(restored.error().code(), ErrorCode::kInvalidArgument);
  for (int k = 0; k < 2; ++k) {
    auto r = odometry.process(frames[static_cast<std::size_t>(k)], {k / 30.0});
    ASSERT_TRUE(r.has_value());
    EXPECT_FALSE(r->relocalising);
    EXPECT_EQ(r->places, k) << "a new map begins at the first frame with motion";
  }
}

}  // namespace
}  // namespace omnipose
