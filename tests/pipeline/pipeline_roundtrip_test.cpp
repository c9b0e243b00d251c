// Renderer round trip: every sign of DESIGN.md section 3 (roll, pitch, yaw, tx, ty, tz) is
// recovered in sign and magnitude from rendered frames, for omni and panorama input and
// for every lens variant (azimuth_direction cw/ccw, outer_edge top/bottom).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "omnipose/pipeline.hpp"
#include "render_fixture.hpp"

using ::testing::HasSubstr;

namespace omnipose {
namespace {

using testing::indoorPhoto;
using testing::relativePose;

struct Case {
  const char* name;
  Eigen::Vector3d omega;  ///< radians
  Eigen::Vector3d t;      ///< metres (box room)
};

/// Motion between `f0` (rendered at identity) and the frame rendered at `T1`, for `input`
/// frames, with the fit's planar-motion prior `planar_motion_deg` (0: tau_z free).
FrameMotion estimate(const cv::Mat& f0, const synth::Renderer& renderer,
                     const Calibration& calibration, InputKind input, const Eigen::Isometry3d& T1,
                     double planar_motion_deg = MotionFit::Options{}.planar_motion_deg) {
  PipelineOptions options;
  options.unwrap.input = input;
  options.fit.planar_motion_deg = planar_motion_deg;
  return testing::estimatePair(f0, renderer, calibration, options, T1);
}

class RoundTrip : public ::testing::TestWithParam<InputKind> {
 protected:
  static void SetUpTestSuite() {
    if (!std::filesystem::exists(indoorPhoto())) GTEST_SKIP() << "missing " << indoorPhoto();
  }
  synth::Renderer makeRenderer(const Calibration& c, synth::SceneKind kind) const {
    synth::RenderOptions o;
    o.output = GetParam() == InputKind::kOmni ? synth::OutputKind::kOmni
                                               : synth::OutputKind::kPanorama;
    o.supersample = 2;
    return synth::Renderer(synth::Scene::load(indoorPhoto(), kind), c, o);
  }
};

TEST_P(RoundTrip, RotationSignsAndMagnitudes) {
  const Calibration c;
  const auto renderer = makeRenderer(c, synth::SceneKind::kSphere);
  const cv::Mat f0 = testing::renderFrame(renderer, Eigen::Isometry3d::Identity());
  const double a = 0.05;  // about 2.9 degrees
  for (int axis = 0; axis < 3; ++axis) {
    for (double sign : {1.0, -1.0}) {
      Eigen::Vector3d omega = Eigen::Vector3d::Zero();
      omega[axis] = sign * a;
      const FrameMotion m = estimate(f0, renderer, c, GetParam(), relativePose(omega, {0, 0, 0}));
      EXPECT_EQ(m.estimate.status, FitStatus::kOk);
      EXPECT_LT((m.estimate.omega - omega).cwiseAbs().maxCoeff(), 1e-3)
          << "axis " << axis << " sign " << sign << ": " << m.estimate.omega.transpose();
    }
  }
}

TEST_P(RoundTrip, TranslationDirectionsInABoxRoom) {
  const Calibration c;
  const auto renderer = makeRenderer(c, synth::SceneKind::kBox);
  const cv::Mat f0 = testing::renderFrame(renderer, Eigen::Isometry3d::Identity());
  for (int axis = 0; axis < 3; ++axis) {
    for (double sign : {1.0, -1.0}) {
      Eigen::Vector3d t = Eigen::Vector3d::Zero();
      t[axis] = sign * (axis == 2 ? 0.05 : 0.1);
      // tau_z free: a ground robot's planar prior (on by default) would hold the vertical ones.
      const FrameMotion m =
          estimate(f0, renderer, c, GetParam(), relativePose({0, 0, 0}, t), 0.0);
      EXPECT_NE(m.estimate.status, FitStatus::kLost);
      const double angle = std::acos(std::clamp(m.translation_direction.dot(t.normalized()), -1.0, 1.0));
      EXPECT_LT(angle, 10.0 * std::numbers::pi / 180) << "axis " << axis << " sign " << sign
                                                      << ": " << m.translation_direction.transpose();
      EXPECT_LT(m.estimate.omega.norm(), 3e-3) << "no rotation was rendered";
    }
  }
}

INSTANTIATE_TEST_SUITE_P(Input, RoundTrip, ::testing::Values(InputKind::kOmni, InputKind::kPanorama),
                         [](const auto& info) {
                           return info.param == InputKind::kOmni ? "omni" : "panorama";
                         });

// Every lens variant must unwrap to the same panorama model: one combined motion checks
// all six signs at once.
TEST(RoundTripLens, EveryAzimuthDirectionAndOuterEdge) {
  if (!std::filesystem::exists(indoorPhoto())) GTEST_SKIP() << "missing " << indoorPhoto();
  const Eigen::Vector3d omega(0.03, -0.02, 0.04);
  for (auto dir : {AzimuthDirection::kCw, AzimuthDirection::kCcw}) {
    for (auto edge : {OuterEdge::kTop, OuterEdge::kBottom}) {
      Calibration c;
      c.omni.azimuth_direction = dir;
      c.omni.outer_edge = edge;
      c.omni.azimuth_zero_deg = 70.0;
      c.omni.center_x = 352.0;
      synth::RenderOptions o;
      o.supersample = 2;
      const synth::Renderer renderer(synth::Scene::load(indoorPhoto(), synth::SceneKind::kSphere),
                                     c, o);
      const FrameMotion m =
          testing::estimatePair(renderer, c, {}, relativePose(omega, {0, 0, 0}));  // omni input
      EXPECT_LT((m.estimate.omega - omega).cwiseAbs().maxCoeff(), 1e-3)
          << (dir == AzimuthDirection::kCw ? "cw" : "ccw") << "/"
          << (edge == OuterEdge::kTop ? "top" : "bottom") << ": " << m.estimate.omega.transpose();
    }
  }
}

TEST(Pipeline, BadFramesLeaveTheStateUntouched) {
  const Calibration c;
  Pipeline pipeline(c, {});
  const cv::Mat good(720, 720, CV_8UC1, cv::Scalar(0));
  cv::Mat textured(720, 720, CV_8UC1);
  cv::randu(textured, 0, 255);
  ASSERT_TRUE(pipeline.process(textured).has_value());
  auto wrong = pipeline.process(cv::Mat(480, 640, CV_8UC1, cv::Scalar(128)));
  ASSERT_FALSE(wrong.has_value());
  EXPECT_EQ(wrong.error().code(), ErrorCode::kBadFrame);
  EXPECT_THAT(wrong.error().message(), HasSubstr("640x480"));
  auto black = pipeline.process(good);
  ASSERT_FALSE(black.has_value());
  EXPECT_THAT(black.error().message(), HasSubstr("black"));
  // The next good frame is compared with the last good one: identical, so no motion.
  auto same = pipeline.process(textured);
  ASSERT_TRUE(same.has_value());
  EXPECT_TRUE(same->has_motion);
  EXPECT_LT(same->estimate.omega.norm(), 1e-4);
}

TEST(Pipeline, InvalidOptionsListEveryProblem) {
  PipelineOptions o;
  o.registration.window = 200;  // taller than the panorama
  o.fit.huber_delta_px = -1;
  o.refine_iterations = 9;
  try {
    Pipeline p(Calibration{}, o);
    FAIL();
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_THAT(what, HasSubstr("window"));
    EXPECT_THAT(what, HasSubstr("huber_delta_px"));
    EXPECT_THAT(what, HasSubstr("refine_iterations"));
  }
  // The same list without building anything, each keyed by its field in PipelineOptions.
  const auto problems = Pipeline::validate(Calibration{}, o);
  ASSERT_EQ(problems.size(), 3u);
  EXPECT_EQ(problems[0].rfind("registration.window: 200 is larger than the panorama", 0), 0u)
      << problems[0];
  EXPECT_EQ(problems[1], "fit.huber_delta_px: -1 is outside (0, 100] pixels");
  EXPECT_EQ(problems[2], "refine_iterations: 9 is outside [0, 5]");
  EXPECT_TRUE(Pipeline::validate(Calibration{}, PipelineOptions{}).empty());
  // An invalid calibration is named as such, and the window is then checked on its own.
  Calibration broken;
  broken.panorama.height = 0;
  const auto with_calibration = Pipeline::validate(broken, PipelineOptions{});
  ASSERT_FALSE(with_calibration.empty());
  for (const auto& p : with_calibration) EXPECT_EQ(p.rfind("calibration: ", 0), 0u) << p;
}

}  // namespace
}  // namespace omnipose
