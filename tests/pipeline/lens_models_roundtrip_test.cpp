// Renderer round trip through non-linear lenses: frames rendered through an
// OCamCalib mirror (real and made-up) and a Mei (cv::omnidir) lens, unwrapped with the
// same model, give back the rendered rotation and translation in sign and magnitude.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "omnipose/pipeline.hpp"
#include "render_fixture.hpp"
#include "test_figures.hpp"

namespace omnipose {
namespace {

using testing::indoorPhoto;
using testing::relativePose;

const std::filesystem::path kData = std::filesystem::path(OMNIPOSE_SOURCE_DIR) / "tests/data/catadioptric";

Calibration lens(const std::string& name) {
  if (name == "mei") {
    return Calibration::parse(R"(omni:
  model: mei
  image_width: 800
  image_height: 800
  xi: 0.92
  K: [205.0, 0.3, 401.5, 0, 204.2, 398.0, 0, 0, 1]
  D: [-0.04, 0.006, 0.0004, -0.0003]
  radius_inner: 90
  radius_outer: 330
  azimuth_zero_deg: 25
  azimuth_direction: ccw
panorama: {width: 1100, height: 110}
)", "mei.yaml");
  }
  return Calibration::parse("omni:\n  model: ocamcalib\n  ocamcalib_file: " + name +
                                "\n  azimuth_zero_deg: -40\npanorama: {width: 1100, height: 110}\n",
                            name, kData);
}

/// The test photo as `scene` seen through `c`, one ray per pixel: the errors stay 40 times
/// below the bounds checked (omega_error_rad, *_direction_error_rad), as they were at 2 x 2
/// rays.
synth::Renderer rendererFor(const Calibration& c, synth::SceneKind scene) {
  synth::RenderOptions o;
  o.supersample = 1;
  return synth::Renderer(synth::Scene::load(indoorPhoto(), scene), c, o);
}

class LensRoundTrip : public ::testing::TestWithParam<std::string> {};

TEST_P(LensRoundTrip, CombinedRotation) {
  if (!std::filesystem::exists(indoorPhoto())) GTEST_SKIP() << "missing " << indoorPhoto();
  const Calibration c = lens(GetParam());
  const Eigen::Vector3d omega(0.03, -0.02, 0.04);
  const FrameMotion m = testing::estimatePair(rendererFor(c, synth::SceneKind::kSphere), c, {},
                                              relativePose(omega, {0, 0, 0}));
  EXPECT_EQ(m.estimate.status, FitStatus::kOk);
  const double error =
      testing::recordFigure("omega_error_rad", (m.estimate.omega - omega).cwiseAbs().maxCoeff(), 6);
  EXPECT_LT(error, 1e-3) << m.estimate.omega.transpose();
}

TEST_P(LensRoundTrip, ForwardAndLeftTranslation) {
  if (!std::filesystem::exists(indoorPhoto())) GTEST_SKIP() << "missing " << indoorPhoto();
  const Calibration c = lens(GetParam());
  const synth::Renderer room = rendererFor(c, synth::SceneKind::kBox);
  const cv::Mat f0 = testing::renderFrame(room, Eigen::Isometry3d::Identity());
  for (const Eigen::Vector3d& t : {Eigen::Vector3d(0.1, 0, 0), Eigen::Vector3d(0, -0.1, 0)}) {
    const FrameMotion m = testing::estimatePair(f0, room, c, {}, relativePose({0, 0, 0}, t));
    const double angle = testing::recordFigure(
        t.x() != 0 ? "forward_direction_error_rad" : "left_direction_error_rad",
        std::acos(std::clamp(m.translation_direction.dot(t.normalized()), -1.0, 1.0)), 4);
    EXPECT_LT(angle, 10.0 * std::numbers::pi / 180) << m.translation_direction.transpose();
    EXPECT_LT(m.estimate.omega.norm(), 3e-3) << "no rotation was rendered";
  }
}

INSTANTIATE_TEST_SUITE_P(Lens, LensRoundTrip,
                         ::testing::Values("steep_mirror_800_ocamcalib.txt",
                                           "mirror_office_ocamcalib.txt", "mei"),
                         [](const auto& info) {
                           const std::string& n = info.param;
                           return n == "mei" ? std::string("mei") : n.substr(0, n.find('_', 7));
                         });

}  // namespace
}  // namespace omnipose
