#pragma once
// Shared helpers for tests that render frame pairs with the exact renderer.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <numbers>
#include <string>

#include "omnipose/io/trajectory.hpp"
#include "omnipose/pipeline.hpp"
#include "omnipose/so3.hpp"
#include "omnipose/synth/synth.hpp"

namespace omnipose::testing {

/// The bundled indoor photo (tests/data/equirect, MIT-licensed).
inline std::filesystem::path indoorPhoto() {
  return std::filesystem::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg";
}

/// The relative pose [exp(omega) | t] as a TUM-style camera pose (frame 0 at identity).
inline Eigen::Isometry3d relativePose(const Eigen::Vector3d& omega, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationFromVector(omega);
  T.translation() = t;
  return T;
}

/// `renderer`'s frame at `T`, 8-bit.
inline cv::Mat renderFrame(const synth::Renderer& renderer, const Eigen::Isometry3d& T) {
  cv::Mat frame;
  renderer.render(T).convertTo(frame, CV_8U);
  return frame;
}

/// Runs `f0` (the frame at identity, renderFrame) and the frame rendered at `T1` through a
/// fresh pipeline built with `options`; the second frame's motion (a failure of either
/// process() call is a test failure, and then an empty FrameMotion is returned).
inline FrameMotion estimatePair(const cv::Mat& f0, const synth::Renderer& renderer,
                                const Calibration& calibration, const PipelineOptions& options,
                                const Eigen::Isometry3d& T1) {
  Pipeline pipeline(calibration, options);
  const cv::Mat f1 = renderFrame(renderer, T1);
  EXPECT_TRUE(pipeline.process(f0).has_value());
  auto m = pipeline.process(f1);
  EXPECT_TRUE(m.has_value()) << (m ? "" : m.error().c_str());
  if (!m) return {};
  EXPECT_TRUE(m->has_motion);
  return *m;
}

/// As above, the frame at identity rendered too.
inline FrameMotion estimatePair(const synth::Renderer& renderer, const Calibration& calibration,
                                const PipelineOptions& options, const Eigen::Isometry3d& T1) {
  return estimatePair(renderFrame(renderer, Eigen::Isometry3d::Identity()), renderer, calibration,
                      options, T1);
}

/// Yaw (rad) of frame k of a slow turn of 0.3 to 0.6 deg per frame (the people and
/// real-camera benchmarks' `slow_turn`).
inline double slowTurnYaw(int k) {
  double angle = 0.0;
  for (int i = 1; i <= k; ++i) {
    angle += (0.45 + 0.15 * std::sin(1.9 * i)) * std::numbers::pi / 180.0;
  }
  return angle;
}

/// Pose of frame k of the slow turn: slowTurnYaw(k) about the camera's z axis, no translation.
inline Eigen::Isometry3d slowTurnPose(int k) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationFromVector(Eigen::Vector3d(0.0, 0.0, slowTurnYaw(k)));
  return T;
}

/// `renderer`'s frame at `pose` and `time_s` (its walkers' clock) with Gaussian sensor noise
/// of `sigma` grey levels drawn from `rng`, 8-bit.
inline cv::Mat noisyFrame(const synth::Renderer& renderer, const Eigen::Isometry3d& pose,
                          double time_s, cv::RNG& rng, double sigma = 3.0) {
  cv::Mat image = renderer.render(pose, time_s);
  cv::Mat noise(image.size(), CV_32FC1);
  rng.fill(noise, cv::RNG::NORMAL, 0.0, sigma);
  cv::Mat frame;
  cv::Mat(image + noise).convertTo(frame, CV_8U);
  return frame;
}

/// RMS rotation error angle (rad) of `pipeline` over a sequence of `frames` frames:
/// `frame(k)` gives frame k (8-bit), `attitude(k)` the camera's true attitude then (a
/// rotation matrix). A failed process() call, and a pair after the first frame without
/// motion, are test failures.
template <class FrameOf, class AttitudeOf>
double rmsRotationError(Pipeline& pipeline, int frames, FrameOf&& frame, AttitudeOf&& attitude) {
  double sum_sq = 0.0;
  for (int k = 0; k < frames; ++k) {
    auto m = pipeline.process(frame(k));
    EXPECT_TRUE(m.has_value()) << (m ? "" : m.error().c_str());
    if (!m || k == 0) continue;
    EXPECT_TRUE(m->has_motion) << k;
    const Eigen::Matrix3d truth = attitude(k - 1).transpose() * attitude(k);
    sum_sq += rotationVector(truth.transpose() * m->rotation).squaredNorm();
  }
  return std::sqrt(sum_sq / (frames - 1));
}

/// rmsRotationError() of a pipeline with `options` over `frames` frames of `renderer` at 30 fps,
/// frame k at `pose(k)` (an Eigen::Isometry3d) with noisyFrame()'s noise drawn from `seed`.
template <class PoseOf>
double rmsRotationErrorOf(const synth::Renderer& renderer, const PipelineOptions& options,
                          int frames, PoseOf&& pose, std::uint64_t seed) {
  Pipeline pipeline(Calibration{}, options);
  cv::RNG rng(seed);
  const auto frame = [&](int k) { return noisyFrame(renderer, pose(k), k / 30.0, rng); };
  const auto attitude = [&](int k) -> Eigen::Matrix3d { return pose(k).linear(); };
  return rmsRotationError(pipeline, frames, frame, attitude);
}

}  // namespace omnipose::testing
