// The per-frame path allocates nothing: global operator new is replaced in this binary and
// counted while Pipeline::process runs on 200 frames after warm-up (including a rejected
// frame and a reset, which must not allocate either).
#include <gtest/gtest.h>

#include <atomic>
#include <cstdlib>
#include <new>

#include "omnipose/pipeline.hpp"
#include "render_fixture.hpp"

namespace {
std::atomic<long> g_allocations{0};
std::atomic<bool> g_counting{false};
}  // namespace

void* operator new(std::size_t size) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1);
  if (void* p = std::malloc(size ? size : 1)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size) { return operator new(size); }
void* operator new(std::size_t size, std::align_val_t align) {
  if (g_counting.load(std::memory_order_relaxed)) g_allocations.fetch_add(1);
  const std::size_t a = static_cast<std::size_t>(align);
  if (void* p = std::aligned_alloc(a, (size + a - 1) / a * a)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t size, std::align_val_t align) { return operator new(size, align); }
void operator delete(void* p) noexcept { std::free(p); }
void operator delete[](void* p) noexcept { std::free(p); }
void operator delete(void* p, std::size_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t) noexcept { std::free(p); }
void operator delete(void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::align_val_t) noexcept { std::free(p); }
void operator delete(void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }
void operator delete[](void* p, std::size_t, std::align_val_t) noexcept { std::free(p); }

namespace omnipose {
namespace {

TEST(PipelineAllocation, ProcessAllocatesNothingAfterWarmUp) {
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

  Pipeline pipeline(Calibration{}, {});
  for (int k = 0; k < 4; ++k) ASSERT_TRUE(pipeline.process(frames[k]).has_value());  // warm-up
  ASSERT_TRUE(pipeline.process(colour).has_value());

  g_allocations = 0;
  g_counting = true;
  int ok = 0;
  for (int i = 0; i < 200; ++i) {
    if (pipeline.process(frames[i % 4]).has_value()) ++ok;
    if (i == 50) (void)pipeline.process(wrong_size);  // rejected frame
    if (i == 100) pipeline.reset();
    if (i == 150) (void)pipeline.process(colour);
  }
  g_counting = false;
  EXPECT_EQ(ok, 200);
  EXPECT_EQ(g_allocations.load(), 0) << "heap allocations in 200 frames of Pipeline::process";
}

}  // namespace
}  // namespace omnipose
