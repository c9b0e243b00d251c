// Auto-exposure steps and lens vignetting do not move the estimate: without sensor noise, a
// sequence whose frames change brightness by 25 % steps and fall off towards the ring's
// outer edge gives the same rotations as the plain sequence, against the exact renderer.
// (With sensor noise the two effects lower the signal against the same noise, which costs
// accuracy as any darker image does: docs/results/ANALYSIS.md, "Auto-exposure and
// vignetting".)
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <numbers>

#include "omnipose/pipeline.hpp"
#include "omnipose/so3.hpp"
#include "omnipose/synth/synth.hpp"
#include "render_fixture.hpp"
#include "test_figures.hpp"

namespace omnipose {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;
constexpr int kFrames = 9;

/// Camera attitude of frame k: steps of 1.5-3 deg about axes that mix yaw with roll and pitch.
Eigen::Matrix3d attitude(int k) {
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  for (int i = 1; i <= k; ++i) {
    const Eigen::Vector3d axis =
        Eigen::Vector3d(0.3 * std::sin(1.7 * i), 0.3 * std::cos(2.3 * i), 1.0).normalized();
    R = R * rotationFromVector(axis * (1.5 + 0.2 * i) * kDeg);
  }
  return R;
}

/// RMS rotation error angle (rad) of the pipeline over the sequence; frame k is rendered,
/// multiplied by gain[k] and, with `vignetting`, by the lens falloff, then rounded to 8 bits
/// (saturating at 255, as a sensor does).
double rmsError(const synth::Renderer& renderer, const std::array<double, kFrames>& gain,
                const synth::Vignetting* vignetting) {
  Pipeline pipeline(Calibration{}, PipelineOptions{});
  const auto frame = [&](int k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = attitude(k);
    cv::Mat image = renderer.render(T);
    if (vignetting != nullptr) vignetting->apply(image, Calibration{}, synth::OutputKind::kOmni);
    cv::Mat frame;
    image.convertTo(frame, CV_8U, gain[static_cast<std::size_t>(k)]);
    return frame;
  };
  return testing::rmsRotationError(pipeline, kFrames, frame, attitude);
}

TEST(Brightness, ExposureStepsAndVignettingDoNotMoveTheEstimate) {
  const synth::Renderer renderer(
      synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kSphere), Calibration{});
  // Gain steps of x1.25 up and down between most pairs, as the real-camera benchmark's
  // auto-exposure, around 0.8 so that no frame clips: clipping is not what this checks
  // (highlights that saturate in one frame and not in the other do move the estimate:
  // ANALYSIS.md).
  std::array<double, kFrames> flat{};
  flat.fill(0.8);
  const std::array<double, kFrames> steps = {0.8, 1.0, 0.8, 0.64, 0.8, 1.0, 0.8, 0.64, 0.8};
  const synth::Vignetting vignetting{0.3};
  const double plain = testing::recordFigure("plain_rms_rad", rmsError(renderer, flat, nullptr), 9);
  const double stepped =
      testing::recordFigure("exposure_steps_rms_rad", rmsError(renderer, steps, nullptr), 9);
  const double both = testing::recordFigure("steps_and_vignetting_rms_rad",
                                            rmsError(renderer, steps, &vignetting), 9);
  ASSERT_GT(plain, 0.0);
  // Phase correlation whitens each window's spectrum: a gain cancels, and a falloff that
  // both frames share is a fixed factor of both windows. What is left is the 8-bit rounding,
  // the only noise here, against a signal the darker frames and the falloff (down to 0.7 at
  // the ring's outer edge) make smaller.
  EXPECT_LT(stepped, 1.1 * plain) << "plain " << plain << " rad, with steps " << stepped;
  EXPECT_LT(both, 1.25 * plain) << "plain " << plain << " rad, steps and vignetting " << both;
}

}  // namespace
}  // namespace omnipose
