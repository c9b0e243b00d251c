// The per-frame path allocates nothing: every heap allocation of the process (malloc
// family and operator new, so FFTW's and OpenCV's count too) is counted while
// Pipeline::process runs on 100 frames after warm-up, including a rejected frame, a reset
// and a colour frame, which must not allocate either. The frames turn in place in a distant
// scene, or drive through a box room (whose translation the fit predicts each window's
// de-warp from with PipelineOptions::dewarp_by_fit). (The counter itself is tested in
// tests/support/allocation_counter_test.cpp.)
#include <gtest/gtest.h>

#include <algorithm>
#include <cstdlib>
#include <ostream>
#include <string>
#include <tuple>
#include <vector>

#include "allocation_counter.hpp"
#include "omnipose/pipeline.hpp"
#include "render_fixture.hpp"

namespace omnipose {
namespace {

enum class Motion { kTurning, kDriving };

std::string motionName(Motion motion) { return motion == Motion::kDriving ? "Driving" : "Turning"; }
void PrintTo(Motion motion, std::ostream* os) { *os << motionName(motion); }

/// (threads, PipelineOptions::dewarp_by_fit, the frames' motion).
class PipelineAllocation : public ::testing::TestWithParam<std::tuple<int, bool, Motion>> {};

/// Four frames, 8-bit: turning about all three axes in a distant scene, or driving 3 cm a
/// frame through a box room while turning 0.3 deg a frame (the pair from the last frame back
/// to the first drives 9 cm back).
std::vector<cv::Mat> renderFrames(Motion motion) {
  synth::RenderOptions ro;
  ro.supersample = 2;
  const bool driving = motion == Motion::kDriving;
  const synth::Renderer renderer(
      synth::Scene::load(testing::indoorPhoto(),
                         driving ? synth::SceneKind::kBox : synth::SceneKind::kSphere),
      Calibration{}, ro);
  std::vector<cv::Mat> frames(4);
  for (int k = 0; k < 4; ++k) {
    const Eigen::Isometry3d pose =
        driving ? testing::relativePose(Eigen::Vector3d(0, 0, 0.005 * k), {0.03 * k, 0.01 * k, 0})
                : testing::relativePose(Eigen::Vector3d(0.01 * k, -0.005 * k, 0.03 * k), {0, 0, 0});
    frames[k] = testing::renderFrame(renderer, pose);
  }
  return frames;
}

TEST_P(PipelineAllocation, ProcessAllocatesNothingAfterWarmUp) {
  if (!testing::AllocationCounter::available())
    GTEST_SKIP() << "sanitizer build: the sanitizer owns malloc, allocations are not counted";
  if (!std::filesystem::exists(testing::indoorPhoto())) GTEST_SKIP() << "missing photo";
  cv::setNumThreads(1);  // OpenCV's thread pool would allocate its own task objects
  const auto [threads, dewarp_by_fit, motion] = GetParam();
  const std::vector<cv::Mat> frames = renderFrames(motion);
  cv::Mat colour;
  cv::merge(std::vector<cv::Mat>{frames[0], frames[0], frames[0]}, colour);
  const cv::Mat wrong_size(100, 100, CV_8UC1, cv::Scalar(7));

  PipelineOptions options;
  options.threads = threads;  // the worker pool's hand-off must not allocate either
  options.dewarp_by_fit = dewarp_by_fit;
  Pipeline pipeline(Calibration{}, options);
  ASSERT_EQ(pipeline.threads(), threads);
  const auto warmUp = [&](Pipeline& p) {
    for (int k = 0; k < 4; ++k) ASSERT_TRUE(p.process(frames[k]).has_value());
    ASSERT_TRUE(p.process(colour).has_value());
  };
  warmUp(pipeline);
  if (HasFatalFailure()) return;

  // Each frame's rotation, to compare with a pipeline without the option (reserved here:
  // push_back below does not allocate).
  std::vector<Eigen::Matrix3d> rotations;
  rotations.reserve(100);
  const auto run = [&](Pipeline& p, std::vector<Eigen::Matrix3d>* out) {
    int ok = 0;
    for (int i = 0; i < 100; ++i) {
      if (auto m = p.process(frames[i % 4])) {
        ++ok;
        if (out != nullptr) out->push_back(m->rotation);
      }
      if (i == 25) (void)p.process(wrong_size);  // rejected frame
      if (i == 50) p.reset();
      if (i == 75) (void)p.process(colour);
    }
    return ok;
  };
  testing::AllocationCounter counter;  // every thread: the worker pool's too
  const int ok = run(pipeline, &rotations);
  const std::int64_t allocations = counter.stop();
  EXPECT_EQ(ok, 100);
  EXPECT_EQ(allocations, 0) << "heap allocations in 100 frames of Pipeline::process, "
                            << threads << " threads, dewarp_by_fit " << dewarp_by_fit
                            << ", " << motionName(motion);

  if (dewarp_by_fit && motion == Motion::kDriving) {
    // The windows were de-warped by the fit's prediction (predictDewarp()'s predicting
    // branch ran under the counter): the same frames without the option read otherwise.
    PipelineOptions own = options;
    own.dewarp_by_fit = false;
    Pipeline reference(Calibration{}, own);
    warmUp(reference);
    if (HasFatalFailure()) return;
    std::vector<Eigen::Matrix3d> reference_rotations;
    ASSERT_EQ(run(reference, &reference_rotations), 100);
    int differing = 0;
    for (std::size_t i = 0; i < rotations.size(); ++i)
      differing += !rotations[i].isApprox(reference_rotations[i], 1e-7);  // above rounding
    EXPECT_GT(differing, 50) << differing
                             << " of 100 driving pairs read otherwise than without the option";
  }
}

// The scale equations from each window's vertical scale (MotionFit::Options::vertical_scale):
// its profiles and fits allocate nothing either, on one worker or several, and they ran (the
// driving pairs read otherwise than with the log-polar scale).
TEST(PipelineAllocationVerticalScale, ProcessAllocatesNothingAfterWarmUp) {
  if (!testing::AllocationCounter::available())
    GTEST_SKIP() << "sanitizer build: the sanitizer owns malloc, allocations are not counted";
  if (!std::filesystem::exists(testing::indoorPhoto())) GTEST_SKIP() << "missing photo";
  cv::setNumThreads(1);
  const std::vector<cv::Mat> frames = renderFrames(Motion::kDriving);
  for (const int threads : {1, 2}) {
    std::vector<Eigen::Matrix3d> rotations[2];
    for (const bool vertical : {false, true}) {
      PipelineOptions options;
      options.threads = threads;
      options.fit.vertical_scale = vertical;
      Pipeline pipeline(Calibration{}, options);
      for (int k = 0; k < 4; ++k) ASSERT_TRUE(pipeline.process(frames[k]).has_value());
      std::vector<Eigen::Matrix3d>& out = rotations[vertical ? 1 : 0];
      out.reserve(40);
      testing::AllocationCounter counter;
      for (int i = 0; i < 40; ++i)
        if (auto m = pipeline.process(frames[i % 4])) out.push_back(m->rotation);
      const std::int64_t allocations = counter.stop();
      EXPECT_EQ(out.size(), 40u) << threads << " threads, vertical " << vertical;
      EXPECT_EQ(allocations, 0) << "heap allocations in 40 frames, " << threads
                                << " threads, vertical_scale " << vertical;
    }
    int differing = 0;
    for (std::size_t i = 0; i < std::min(rotations[0].size(), rotations[1].size()); ++i)
      differing += !rotations[0][i].isApprox(rotations[1][i], 1e-7);
    EXPECT_GT(differing, 20) << threads << " threads";
  }
}

INSTANTIATE_TEST_SUITE_P(
    Threads, PipelineAllocation,
    ::testing::Combine(::testing::Values(1, 2, 3), ::testing::Bool(),
                       ::testing::Values(Motion::kTurning, Motion::kDriving)),
    [](const ::testing::TestParamInfo<PipelineAllocation::ParamType>& info) {
      return std::to_string(std::get<0>(info.param)) + "Threads" +
             (std::get<1>(info.param) ? "DewarpByFit" : "") + motionName(std::get<2>(info.param));
    });

}  // namespace
}  // namespace omnipose
