// Frames that decode but are not the scene of this moment (omnipose/odometry.hpp,
// PlausibilityOptions) against the exact renderer: a glitching camera's flipped, rotated,
// noise, foreign, torn and repeated frame mid-sequence is not believed, counted, and the
// chain after it ends where the clean run's does; the clean run is not touched; a camera at
// rest may repeat itself; a view that stays unbelievable starts a new segment.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <numbers>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "omnipose/odometry.hpp"
#include "omnipose/so3.hpp"
#include "omnipose/synth/synth.hpp"
#include "render_fixture.hpp"

using ::testing::HasSubstr;

namespace omnipose {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr int kFrames = 24;
constexpr int kGlitch = 12;

Eigen::Isometry3d truthAt(int k) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = (Eigen::AngleAxisd(2.5 * k * kDeg, Eigen::Vector3d::UnitZ()) *
                Eigen::AngleAxisd(1.5 * std::sin(0.5 * k) * kDeg, Eigen::Vector3d::UnitY()) *
                Eigen::AngleAxisd(1.0 * std::sin(0.3 * k) * kDeg, Eigen::Vector3d::UnitX()))
                   .toRotationMatrix();
  return T;
}

/// The sequence: a turn of 2.5 deg per frame with roll and pitch, sensor noise sigma 2.
/// The clean sequence's frames, at least its first `count` (rendered on first use, each once:
/// frame k is the same whichever test asks first).
const std::vector<cv::Mat>& cleanFrames(int count = kFrames) {
  static std::vector<cv::Mat> frames;
  if (static_cast<int>(frames.size()) < count) {
    const synth::Renderer renderer(synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kSphere),
                                   Calibration{}, {});
    synth::DegradeOptions noise;
    noise.noise_sigma = 2.0;
    for (int k = static_cast<int>(frames.size()); k < count; ++k)
      frames.push_back(synth::degrade(renderer.render(truthAt(k)), noise, static_cast<std::uint64_t>(k)));
  }
  return frames;
}

/// A frame of another camera: the real catadioptric photo, grey, at the frame size.
cv::Mat foreignFrame() {
  const std::string path = std::string(OMNIPOSE_SOURCE_DIR)
                               .append("/tests/data/catadioptric/mirror_office_1920x1080.jpg");
  const cv::Mat photo = cv::imread(path, cv::IMREAD_GRAYSCALE);
  cv::Mat out;
  cv::resize(photo, out, cleanFrames(1)[0].size(), 0, 0, cv::INTER_AREA);
  return out;
}

struct OdometryRun {
  std::vector<OdometryResult> results;  ///< of the frames believed
  std::vector<int> rejected;            ///< frames answered kImplausible
  std::vector<std::string> messages;
};

/// Processes `frames` (timestamps k / 30 s) with `options`.
OdometryRun runOdometry(const std::vector<cv::Mat>& frames, const OdometryOptions& options = {}) {
  Odometry odometry(Calibration{}, options);
  OdometryRun run;
  for (int k = 0; k < static_cast<int>(frames.size()); ++k) {
    auto r = odometry.process(frames[static_cast<std::size_t>(k)], {k / 30.0, k});
    if (r) {
      run.results.push_back(*r);
    } else {
      EXPECT_EQ(r.error().code(), ErrorCode::kImplausible) << "frame " << k << ": " << r.error().c_str();
      run.rejected.push_back(k);
      run.messages.emplace_back(r.error().message());
    }
  }
  return run;
}

double angleBetween(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return rotationVector(a.linear().transpose() * b.linear()).norm();
}

TEST(Glitches, TheCleanRunIsBelievedWholeAndUntouchedByTheChecks) {
  const OdometryRun on = runOdometry(cleanFrames());
  OdometryOptions off_options;
  off_options.plausibility.enabled = false;
  const OdometryRun off = runOdometry(cleanFrames(), off_options);
  EXPECT_TRUE(on.rejected.empty());
  ASSERT_EQ(on.results.size(), off.results.size());
  for (std::size_t k = 0; k < on.results.size(); ++k) {
    EXPECT_EQ(on.results[k].state, off.results[k].state);
    EXPECT_TRUE(on.results[k].pose.matrix() == off.results[k].pose.matrix()) << "frame " << k << " not bit-identical";
  }
  EXPECT_LT(angleBetween(on.results.back().pose, truthAt(kFrames - 1)), 0.05 * kDeg);
}

struct Glitch {
  const char* name;
  std::function<cv::Mat(const std::vector<cv::Mat>&)> make;  ///< from the clean frames
  const char* says;
};

std::vector<Glitch> glitches() {
  return {
      {"flipped", [](const auto& f) { cv::Mat g; cv::flip(f[kGlitch], g, 0); return g; }, "confidence"},
      {"rotated 90 degrees",
       [](const auto& f) { cv::Mat g; cv::rotate(f[kGlitch], g, cv::ROTATE_90_CLOCKWISE); return g; },
       "confidence"},
      {"noise",
       [](const auto& f) {
         cv::Mat g(f[kGlitch].size(), CV_8UC1);
         cv::randu(g, 0, 255);
         return g;
       },
       "confidence"},
      {"another camera's", [](const auto&) { return foreignFrame(); }, "confidence"},
      {"torn: its upper half the previous frame's",
       [](const auto& f) {
         cv::Mat g = f[kGlitch].clone();
         f[kGlitch - 1].rowRange(0, g.rows / 2).copyTo(g.rowRange(0, g.rows / 2));
         return g;
       },
       "rows with content are the previous frame's"},
      {"repeated", [](const auto& f) { return f[kGlitch - 1].clone(); },
       "rows with content are the previous frame's"},
  };
}

TEST(Glitches, AGlitchedFrameMidSequenceIsNotBelievedAndTheChainEndsWhereTheCleanOneDoes) {
  const OdometryRun clean = runOdometry(cleanFrames());
  ASSERT_EQ(clean.results.size(), static_cast<std::size_t>(kFrames));
  for (const bool keyframes : {false, true}) {
    OdometryOptions options;
    if (keyframes) options.keyframes.slots = 4;
    const OdometryRun reference = keyframes ? runOdometry(cleanFrames(), options) : clean;
    const std::vector<Glitch> all = glitches();
    for (std::size_t i = 0; i < all.size(); ++i) {
      const Glitch& g = all[i];
      SCOPED_TRACE(std::string(g.name) + (keyframes ? ", keyframes on" : ""));
      std::vector<cv::Mat> frames = cleanFrames();
      frames[kGlitch] = g.make(cleanFrames());
      const OdometryRun run = runOdometry(frames, options);
      ASSERT_EQ(run.rejected, std::vector<int>{kGlitch}) << "the glitch, and only it, is counted";
      EXPECT_THAT(run.messages[0], HasSubstr(g.says));
      for (const OdometryResult& r : run.results) {
        EXPECT_EQ(r.segment, 0);
        if (r.sequence == kGlitch + 1) {
          EXPECT_TRUE(r.tracked());
          EXPECT_EQ(r.reference_sequence, kGlitch - 1) << "registered against the frame before the glitch";
        }
      }
      const double off = angleBetween(run.results.back().pose, reference.results.back().pose);
      ::testing::Test::RecordProperty(std::string("end_offset_deg_") + (keyframes ? "kf_" : "") +
                                          std::to_string(i),
                                      std::to_string(off / kDeg));
      EXPECT_LT(off, 0.05 * kDeg) << "the chain after it within 0.05 deg of the clean run's: "
                                  << off / kDeg << " deg";
    }
  }
}

TEST(Glitches, TwoGlitchesInARowAreBothDroppedAndBridged) {
  std::vector<cv::Mat> frames = cleanFrames();
  cv::flip(cleanFrames()[kGlitch], frames[kGlitch], 0);
  frames[kGlitch + 1] = foreignFrame();
  const OdometryRun run = runOdometry(frames);
  EXPECT_EQ(run.rejected, (std::vector<int>{kGlitch, kGlitch + 1}));
  const OdometryRun clean = runOdometry(cleanFrames());
  EXPECT_LT(angleBetween(run.results.back().pose, clean.results.back().pose), 0.05 * kDeg);
  for (const OdometryResult& r : run.results) {
    if (r.sequence == kGlitch + 2) {
      EXPECT_EQ(r.reference_sequence, kGlitch - 1);
    }
  }
}

TEST(Glitches, AViewThatStaysUnbelievableStartsANewSegmentAfterMaxRejected) {
  std::vector<cv::Mat> frames = cleanFrames();
  for (int k = kGlitch; k < kFrames; ++k) {
    frames[static_cast<std::size_t>(k)] = cv::Mat(frames[0].size(), CV_8UC1);
    cv::randu(frames[static_cast<std::size_t>(k)], 0, 255);
  }
  OdometryOptions options;
  options.plausibility.max_rejected = 3;
  const OdometryRun run = runOdometry(frames, options);
  ASSERT_GE(run.rejected.size(), 3u);
  EXPECT_EQ(std::vector<int>(run.rejected.begin(), run.rejected.begin() + 3),
            (std::vector<int>{kGlitch, kGlitch + 1, kGlitch + 2}));
  bool restarted = false;
  for (const OdometryResult& r : run.results) {
    if (r.sequence != kGlitch + 3) continue;
    restarted = true;
    EXPECT_EQ(r.state, TrackState::kLost);
    EXPECT_EQ(r.segment, 1);
    EXPECT_LT(angleBetween(r.pose, run.results[kGlitch - 1].pose), 1e-12) << "the pose is held";
  }
  EXPECT_TRUE(restarted);
}

TEST(Glitches, ACameraAtRestMayRepeatItsFramesExactly) {
  // Renders without noise: a camera that does not move gives bit-identical frames, and
  // nothing says it did not stand still.
  const synth::Renderer renderer(synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kSphere),
                                 Calibration{}, {});
  cv::Mat still;
  renderer.render(truthAt(3)).convertTo(still, CV_8U);
  const OdometryRun run = runOdometry(std::vector<cv::Mat>(6, still));
  EXPECT_TRUE(run.rejected.empty());
  ASSERT_EQ(run.results.size(), 6u);
  EXPECT_EQ(run.results.back().state, TrackState::kTracked);
}

TEST(Glitches, ATurnFasterThanTheRobotCanTurnIsNotBelieved) {
  OdometryOptions options;
  options.plausibility.max_rotation_rad_s = 30.0 * kDeg;  // the turn is 75 deg/s
  options.plausibility.max_rejected = 1000;
  const std::vector<cv::Mat>& clean = cleanFrames(3);  // a turn's first three frames
  const OdometryRun run = runOdometry(std::vector<cv::Mat>(clean.begin(), clean.begin() + 3), options);
  ASSERT_FALSE(run.rejected.empty());
  EXPECT_EQ(run.rejected.front(), 1);
  EXPECT_THAT(run.messages.front(), HasSubstr("faster than the 30 deg/s the robot can turn"));
}

TEST(Glitches, BadOptionsAreNamed) {
  OdometryOptions options;
  options.plausibility.max_repeated_rows = 1.5;
  options.plausibility.min_confidence_ratio = 1.0;
  options.plausibility.max_rotation_rad_s = 0.0;
  options.plausibility.max_rejected = 0;
  const auto problems = Odometry::validate(Calibration{}, options);
  std::string all;
  for (const auto& p : problems) all += p + "\n";
  for (const char* field : {"plausibility.max_repeated_rows", "plausibility.min_confidence_ratio",
                            "plausibility.max_rotation_rad_s", "plausibility.max_rejected"})
    EXPECT_THAT(all, HasSubstr(field)) << field << " in\n" << all;
}

}  // namespace
}  // namespace omnipose
