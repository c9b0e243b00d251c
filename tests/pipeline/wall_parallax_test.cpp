// Driving along a near wall does not turn the robot: a window that sees the wall at an angle
// expands horizontally more than vertically (the wall's distance changes across it), and the
// in-window scale carries part of that. Read as depth alone, it pulled the per-window inverse
// depths and with them the yaw (the drift benchmark's rectangle, docs/results/ANALYSIS.md).
// Noise-free pairs rendered by the exact renderer in the box room, 1 m from a wall.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numbers>
#include <vector>

#include "omnipose/pipeline.hpp"
#include "omnipose/so3.hpp"
#include "omnipose/synth/synth.hpp"
#include "render_fixture.hpp"
#include "test_figures.hpp"

namespace omnipose {
namespace {

constexpr double kStep = 0.02;  ///< metres per frame: 0.6 m/s at 30 fps

/// Camera pose at distance `along` on a straight drive parallel to the room's x = 3 m wall,
/// 1 m from it, facing world +y (the wall on the right).
Eigen::Isometry3d drivePose(double along) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationFromVector(Eigen::Vector3d(0, 0, std::numbers::pi / 2));
  T.translation() = Eigen::Vector3d(2.0, along, 0.0);
  return T;
}

/// The frames of the pairs (along, along + kStep) at four places along the wall, 8-bit.
std::vector<std::array<cv::Mat, 2>> renderPairs(const synth::Renderer& renderer) {
  std::vector<std::array<cv::Mat, 2>> pairs;
  for (double along : {-1.2, -0.6, 0.0, 0.6}) {
    std::array<cv::Mat, 2>& pair = pairs.emplace_back();
    renderer.render(drivePose(along)).convertTo(pair[0], CV_8U);
    renderer.render(drivePose(along + kStep)).convertTo(pair[1], CV_8U);
  }
  return pairs;
}

/// RMS yaw error (rad) of the pipeline over `pairs` with `scale_depth_gradient`.
double rmsYawError(const std::vector<std::array<cv::Mat, 2>>& pairs, double scale_depth_gradient) {
  PipelineOptions options;
  options.unwrap.input = InputKind::kPanorama;
  options.fit.scale_depth_gradient = scale_depth_gradient;
  double sum_sq = 0.0;
  int measured = 0;
  for (std::size_t p = 0; p < pairs.size(); ++p) {
    Pipeline pipeline(Calibration{}, options);
    EXPECT_TRUE(pipeline.process(pairs[p][0]).has_value()) << p;
    auto m = pipeline.process(pairs[p][1]);
    EXPECT_TRUE(m.has_value()) << p << ": " << (m ? "" : m.error().c_str());
    if (!m) continue;
    EXPECT_TRUE(m->has_motion) << p;
    EXPECT_NE(m->estimate.status, FitStatus::kLost) << p;
    // The camera only moved forward: every rotation is error.
    const double yaw = rotationVector(m->rotation).z();
    sum_sq += yaw * yaw;
    ++measured;
  }
  return measured > 0 ? std::sqrt(sum_sq / measured) : 1.0;
}

TEST(WallParallax, DrivingAlongANearWallDoesNotTurn) {
  if (!std::filesystem::exists(testing::indoorPhoto()))
    GTEST_SKIP() << "missing " << testing::indoorPhoto();
  synth::RenderOptions o;
  o.output = synth::OutputKind::kPanorama;
  o.supersample = 2;
  const synth::Renderer renderer(synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kBox),
                                 Calibration{}, o);
  const auto pairs = renderPairs(renderer);
  const double with_term = rmsYawError(pairs, 0.5);
  const double without = rmsYawError(pairs, 0.0);
  testing::recordFigure("yaw_rms_rad_with_gradient_term", with_term, 6);
  testing::recordFigure("yaw_rms_rad_without", without, 6);
  EXPECT_LT(with_term, 0.25 * without);
  EXPECT_LT(with_term, 3e-4);
}

}  // namespace
}  // namespace omnipose
