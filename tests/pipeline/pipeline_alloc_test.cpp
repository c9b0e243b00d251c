// The per-frame path allocates nothing: every heap allocation of the process (malloc
// family and operator new, so FFTW's and OpenCV's count too) is counted while
// Pipeline::process runs on 100 frames after warm-up, including a rejected frame, a reset
// and a colour frame, which must not allocate either. (The counter itself is tested in
// tests/support/allocation_counter_test.cpp.)
#include <gtest/gtest.h>

#include <cstdlib>
#include <tuple>

#include "allocation_counter.hpp"
#include "omnipose/pipeline.hpp"
#include "render_fixture.hpp"

namespace omnipose {
namespace {

/// (threads, PipelineOptions::dewarp_by_fit).
class PipelineAllocation : public ::testing::TestWithParam<std::tuple<int, bool>> {};

TEST_P(PipelineAllocation, ProcessAllocatesNothingAfterWarmUp) {
  if (!testing::AllocationCounter::available())
    GTEST_SKIP() << "sanitizer build: the sanitizer owns malloc, allocations are not counted";
  if (!std::filesystem::exists(testing::indoorPhoto())) GTEST_SKIP() << "missing photo";
  cv::setNumThreads(1);  // OpenCV's thread pool would allocate its own task objects
  synth::RenderOptions ro;
  ro.supersample = 2;
  const synth::Renderer renderer(synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kSphere),
                                 Calibration{}, ro);
  std::vector<cv::Mat> frames(4);
  for (int k = 0; k < 4; ++k) {
    renderer.render(testing::relativePose(Eigen::Vector3d(0.01 * k, -0.005 * k, 0.03 * k), {0, 0, 0}))
        .convertTo(frames[k], CV_8U);
  }
  cv::Mat colour;
  cv::merge(std::vector<cv::Mat>{frames[0], frames[0], frames[0]}, colour);
  const cv::Mat wrong_size(100, 100, CV_8UC1, cv::Scalar(7));

  PipelineOptions options;
  const auto [threads, dewarp_by_fit] = GetParam();
  options.threads = threads;  // the worker pool's hand-off must not allocate either
  options.dewarp_by_fit = dewarp_by_fit;
  Pipeline pipeline(Calibration{}, options);
  ASSERT_EQ(pipeline.threads(), threads);
  for (int k = 0; k < 4; ++k) ASSERT_TRUE(pipeline.process(frames[k]).has_value());  // warm-up
  ASSERT_TRUE(pipeline.process(colour).has_value());

  testing::AllocationCounter counter;  // every thread: the worker pool's too
  int ok = 0;
  for (int i = 0; i < 100; ++i) {
    if (pipeline.process(frames[i % 4]).has_value()) ++ok;
    if (i == 25) (void)pipeline.process(wrong_size);  // rejected frame
    if (i == 50) pipeline.reset();
    if (i == 75) (void)pipeline.process(colour);
  }
  const std::int64_t allocations = counter.stop();
  EXPECT_EQ(ok, 100);
  EXPECT_EQ(allocations, 0) << "heap allocations in 100 frames of Pipeline::process, "
                            << threads << " threads, dewarp_by_fit " << dewarp_by_fit;
}

INSTANTIATE_TEST_SUITE_P(Threads, PipelineAllocation,
                         ::testing::Combine(::testing::Values(1, 2, 3), ::testing::Bool()));

}  // namespace
}  // namespace omnipose
