// Tests of the feature-based baselines: each of orb5pt, akaze5pt, orbrot and
// akazerot recovers a rendered +-3 deg yaw within 0.01 rad on omni and panorama input,
// which proves the bearing conversion (PanoramaGeometry::bearing) and OpenGV's (R12, t12)
// convention against DESIGN.md section 2; the five-point solvers recover the direction of a
// rendered forward step; invalid options are rejected naming the field.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <numbers>
#include <string>

#include "omnipose/baselines/feature_motion_estimator.hpp"
#include "omnipose/io/trajectory.hpp"
#include "omnipose/synth/synth.hpp"

using ::testing::HasSubstr;

namespace omnipose::baselines {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kYaw = 3.0 * kPi / 180.0;
const std::filesystem::path kIndoor =
    std::filesystem::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg";

Eigen::Isometry3d pose(const Eigen::Vector3d& omega, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationFromVector(omega);
  T.translation() = t;
  return T;
}

/// 8-bit renders of the indoor photo, cached per (scene, output, pose) so each image is
/// rendered once for the whole test binary.
const cv::Mat& render(synth::SceneKind scene, synth::OutputKind output,
                      const Eigen::Vector3d& omega, const Eigen::Vector3d& t) {
  static std::map<std::string, cv::Mat> cache;
  char key[160];
  std::snprintf(key, sizeof(key), "%d/%d/%.6f,%.6f,%.6f/%.6f,%.6f,%.6f", static_cast<int>(scene),
                static_cast<int>(output), omega.x(), omega.y(), omega.z(), t.x(), t.y(), t.z());
  auto it = cache.find(key);
  if (it == cache.end()) {
    const synth::Renderer renderer(synth::Scene::load(kIndoor, scene), Calibration{},
                                   {output, 3});
    cv::Mat image;
    renderer.render(pose(omega, t)).convertTo(image, CV_8U);
    it = cache.emplace(key, image).first;
  }
  return it->second;
}

FeatureMotionOptions optionsFor(const std::string& method, InputKind input) {
  auto options = FeatureMotionOptions::forMethod(method);
  EXPECT_TRUE(options.has_value()) << method;
  options->unwrap.input = input;
  return *options;
}

/// Relative motion estimated from the frame at `prev` to the frame at `cur`.
FrameMotion estimate(const std::string& method, InputKind input, synth::SceneKind scene,
                     const Eigen::Isometry3d& prev, const Eigen::Isometry3d& cur) {
  const auto output =
      input == InputKind::kOmni ? synth::OutputKind::kOmni : synth::OutputKind::kPanorama;
  FeatureMotionEstimator estimator(Calibration{}, optionsFor(method, input));
  const auto first = estimator.process(render(scene, output, rotationVector(prev.linear()),
                                              prev.translation()));
  EXPECT_TRUE(first.has_value());
  EXPECT_FALSE(first->has_motion);
  const auto second = estimator.process(render(scene, output, rotationVector(cur.linear()),
                                               cur.translation()));
  EXPECT_TRUE(second.has_value());
  return second.value_or(FrameMotion{});
}

struct YawCase {
  std::string method;
  InputKind input;
  double sign;
};

std::string caseName(const testing::TestParamInfo<YawCase>& info) {
  return info.param.method + (info.param.input == InputKind::kOmni ? "_omni" : "_panorama") +
         (info.param.sign > 0 ? "_left" : "_right");
}

class YawTest : public testing::TestWithParam<YawCase> {};

// The camera turns by +-3 deg about z between the frames. DESIGN.md: the relative pose of
// frame 1 w.r.t. frame 0 is inverse(T_0) * T_1 = Rz(+-3 deg), so omega = (0, 0, +-0.0524).
TEST_P(YawTest, RecoversThreeDegreeYawWithinTenMilliradians) {
  const YawCase& c = GetParam();
  const Eigen::Vector3d truth(0, 0, c.sign * kYaw);
  const FrameMotion m = estimate(c.method, c.input, synth::SceneKind::kSphere,
                                 Eigen::Isometry3d::Identity(),
                                 pose(truth, Eigen::Vector3d::Zero()));
  ASSERT_TRUE(m.has_motion);
  ASSERT_NE(m.estimate.status, FitStatus::kLost)
      << m.estimate.windows_total << " matches, " << m.estimate.windows_used << " inliers";
  const Eigen::Vector3d error = rotationVector(m.rotation) - truth;
  EXPECT_LT(error.norm(), 0.01) << "estimated omega " << rotationVector(m.rotation).transpose()
                                << ", true " << truth.transpose();
  EXPECT_NEAR(m.estimate.omega.z(), truth.z(), 0.01);
  EXPECT_GE(m.estimate.windows_used, 50);  // a textured photo gives many inliers
  EXPECT_LT(m.estimate.residual_rms_px, 1.0);
}

/// Every baseline on both inputs, turning left and right.
std::vector<YawCase> allYawCases() {
  std::vector<YawCase> cases;
  for (const InputKind input : {InputKind::kOmni, InputKind::kPanorama}) {
    for (const char* method : {"orb5pt", "akaze5pt", "orbrot", "akazerot"}) {
      for (const double sign : {+1.0, -1.0}) cases.push_back({method, input, sign});
    }
  }
  return cases;
}

INSTANTIATE_TEST_SUITE_P(AllBaselines, YawTest, testing::ValuesIn(allYawCases()), caseName);

// Roll and pitch exercise the elevation part of the bearing (h = gamma (v_h - v)).
TEST(FeatureMotionEstimator, RotationOnlyRecoversRollAndPitch) {
  for (const Eigen::Vector3d& truth : {Eigen::Vector3d(0.04, 0, 0), Eigen::Vector3d(0, -0.04, 0)}) {
    const FrameMotion m = estimate("akazerot", InputKind::kPanorama, synth::SceneKind::kSphere,
                                   Eigen::Isometry3d::Identity(),
                                   pose(truth, Eigen::Vector3d::Zero()));
    ASSERT_NE(m.estimate.status, FitStatus::kLost);
    EXPECT_LT((rotationVector(m.rotation) - truth).norm(), 0.01)
        << rotationVector(m.rotation).transpose() << " vs " << truth.transpose();
  }
}

// A step of 0.3 m forward (+x) and then one to the left (+y) in the box room: the
// translation direction is t/|t| of P_prev = R P_cur + t, i.e. the step itself.
TEST(FeatureMotionEstimator, FivePointRecoversTranslationDirection) {
  for (const std::string method : {"orb5pt", "akaze5pt"}) {
    for (const Eigen::Vector3d& step : {Eigen::Vector3d(0.3, 0, 0), Eigen::Vector3d(0, 0.3, 0)}) {
      const FrameMotion m = estimate(method, InputKind::kPanorama, synth::SceneKind::kBox,
                                     Eigen::Isometry3d::Identity(),
                                     pose(Eigen::Vector3d::Zero(), step));
      ASSERT_NE(m.estimate.status, FitStatus::kLost) << method;
      const double angle =
          std::acos(std::clamp(m.translation_direction.dot(step.normalized()), -1.0, 1.0));
      EXPECT_LT(angle, 0.15) << method << ": direction " << m.translation_direction.transpose()
                             << ", true " << step.normalized().transpose();
      EXPECT_DOUBLE_EQ(m.tau_norm, 1.0);  // scale unobservable: unit by convention
      EXPECT_LT(rotationVector(m.rotation).norm(), 0.01) << method;
    }
  }
}

TEST(FeatureMotionEstimator, RotationOnlyReportsNoTranslation) {
  const FrameMotion m = estimate("orbrot", InputKind::kPanorama, synth::SceneKind::kSphere,
                                 Eigen::Isometry3d::Identity(),
                                 pose(Eigen::Vector3d(0, 0, kYaw), Eigen::Vector3d::Zero()));
  EXPECT_EQ(m.tau_norm, 0.0);
  EXPECT_EQ(m.translation_direction, Eigen::Vector3d::Zero());
}

TEST(FeatureMotionEstimator, TexturelessPairIsLostAndBadFrameIsAnError) {
  FeatureMotionEstimator estimator(Calibration{}, optionsFor("orb5pt", InputKind::kPanorama));
  EXPECT_STREQ(estimator.name(), "orb5pt");
  const cv::Mat flat(110, 1100, CV_8UC1, cv::Scalar(128));
  ASSERT_TRUE(estimator.process(flat).has_value());
  const auto lost = estimator.process(flat);
  ASSERT_TRUE(lost.has_value());
  EXPECT_TRUE(lost->has_motion);
  EXPECT_EQ(lost->estimate.status, FitStatus::kLost);
  EXPECT_EQ(lost->rotation, Eigen::Matrix3d::Identity());

  // Wrong size and all-black frames are errors that leave the state untouched.
  const auto wrong = estimator.process(cv::Mat(100, 100, CV_8UC1, cv::Scalar(128)));
  ASSERT_FALSE(wrong.has_value());
  EXPECT_EQ(wrong.error().code(), ErrorCode::kBadFrame);
  EXPECT_FALSE(estimator.process(cv::Mat(110, 1100, CV_8UC1, cv::Scalar(0))).has_value());

  // After reset the next frame starts a new pair sequence.
  estimator.reset();
  const auto first = estimator.process(flat);
  ASSERT_TRUE(first.has_value());
  EXPECT_FALSE(first->has_motion);
}

TEST(FeatureMotionEstimator, MethodNamesRoundTrip) {
  for (const std::string& name : FeatureMotionOptions::methodNames()) {
    const auto options = FeatureMotionOptions::forMethod(name);
    ASSERT_TRUE(options.has_value()) << name;
    EXPECT_EQ(options->methodName(), name);
    EXPECT_TRUE(options->validate().empty()) << name;
  }
  EXPECT_FALSE(FeatureMotionOptions::forMethod("sift5pt").has_value());
  EXPECT_EQ(FeatureMotionOptions::forMethod("akazerot")->detector, Detector::kAkaze);
  EXPECT_EQ(FeatureMotionOptions::forMethod("akazerot")->solver, Solver::kRotationOnly);
}

/// The first problem validate() reports for options changed by `edit`, or "" if none.
template <typename Edit>
std::string firstProblem(Edit edit, Solver solver = Solver::kFivePoint) {
  FeatureMotionOptions o;
  o.solver = solver;
  edit(o);
  const auto problems = o.validate();
  return problems.empty() ? std::string() : problems.front();
}

TEST(FeatureMotionOptions, InvalidValuesAreRejectedNamingTheField) {
  using O = FeatureMotionOptions;
  const std::vector<std::pair<std::string, std::string>> cases = {
      {"ratio", firstProblem([](O& o) { o.ratio = 1.5; })},
      {"ratio", firstProblem([](O& o) { o.ratio = 0.0; })},
      {"threshold_px", firstProblem([](O& o) { o.threshold_px = -1.0; })},
      {"max_features", firstProblem([](O& o) { o.max_features = 3; })},
      {"wrap_margin_px", firstProblem([](O& o) { o.wrap_margin_px = -2; })},
      {"orb_patch_size", firstProblem([](O& o) { o.orb_patch_size = 2; })},
      {"orb_levels", firstProblem([](O& o) { o.orb_levels = 0; })},
      {"orb_fast_threshold", firstProblem([](O& o) { o.orb_fast_threshold = 0; })},
      {"akaze_threshold", firstProblem([](O& o) { o.akaze_threshold = 0.0; })},
      {"akaze_octaves", firstProblem([](O& o) { o.akaze_octaves = 9; })},
      {"ransac_max_iterations", firstProblem([](O& o) { o.ransac_max_iterations = 0; })},
      {"ransac_probability", firstProblem([](O& o) { o.ransac_probability = 1.0; })},
      {"min_inliers", firstProblem([](O& o) { o.min_inliers = 5; })},  // five-point needs 8
      {"min_inlier_fraction", firstProblem([](O& o) { o.min_inlier_fraction = 2.0; })},
      {"unwrap.min_mean_intensity", firstProblem([](O& o) { o.unwrap.min_mean_intensity = -1; })},
  };
  for (const auto& [field, message] : cases) {
    EXPECT_EQ(message.rfind(field, 0), 0u) << "expected a message about " << field << ", got '"
                                           << message << "'";
  }
  // Rotation-only needs only 2 correspondences per sample.
  EXPECT_EQ(firstProblem([](O& o) { o.min_inliers = 5; }, Solver::kRotationOnly), "");
  EXPECT_NE(firstProblem([](O& o) { o.min_inliers = 1; }, Solver::kRotationOnly), "");
}

TEST(FeatureMotionEstimator, ConstructorListsEveryBadField) {
  FeatureMotionOptions o;
  o.ratio = 2.0;
  o.threshold_px = 0.0;
  try {
    FeatureMotionEstimator estimator(Calibration{}, o);
    FAIL() << "invalid options accepted";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_THAT(what, HasSubstr("ratio"));
    EXPECT_THAT(what, HasSubstr("threshold_px"));
  }
}

}  // namespace
}  // namespace omnipose::baselines
