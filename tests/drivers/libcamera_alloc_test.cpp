// The libcamera source's steady state allocates nothing on the capture thread: next() on a
// fake libcamera (fake_libcamera.hpp) that completes requests from its own thread, for YUYV,
// NV12 and grey. (libcamera itself allocates inside Request::reuse() and queueRequest() on
// the robot; that is libcamera's, outside the source's code.)

#include <gtest/gtest.h>

#include "allocation_counter.hpp"
#include "fake_libcamera.hpp"
#include "libcamera/libcamera_source.hpp"

namespace omnipose {
namespace {

using namespace std::chrono_literals;
using testing::AllocationCounter;
using testing::FakeCameraConfig;
using testing::FakeCameraManager;

class LibcameraAllocTest : public ::testing::TestWithParam<const char*> {};

TEST_P(LibcameraAllocTest, SteadyStateNextAllocatesNothing) {
  ASSERT_TRUE(AllocationCounter::available()) << "this binary is not built under sanitizers";
  auto manager = std::make_shared<FakeCameraManager>();
  FakeCameraConfig config;
  config.formats = {testing::kFakeR8, testing::kFakeNV12, testing::kFakeYUYV};
  config.stride_align = 256;
  manager->plug(config);
  LibcameraOptions o;
  o.width = 640;
  o.height = 480;
  o.format = GetParam();
  LibcameraSource source(o, FakeCameraManager::opener(manager));
  ASSERT_TRUE(source.open());
  cv::Mat out(480, 640, CV_8UC1);
  // Warm up: the first frames, a stale drain, a clock resync.
  for (int i = 0; i < 3; ++i) {
    manager->produce(config.id, 2);
    ASSERT_TRUE(source.next(out, 1000ms));
  }
  std::int64_t allocations = 0;
  int delivered = 0;
  {
    AllocationCounter counter(AllocationCounter::Scope::kThisThread);
    for (int i = 0; i < 50; ++i) {
      {
        // Scripting the fake (posting to its thread) is the test's, not the source's.
        AllocationCounter::ExcludedScope fake;
        manager->produce(config.id, 1 + i % 3);
      }
      if (source.next(out, 1000ms)) ++delivered;
    }
    allocations = counter.stop();
  }
  EXPECT_EQ(delivered, 50);
  EXPECT_EQ(allocations, 0);
  EXPECT_GT(source.stats().stale_dropped, 0u) << "the drain path ran";
  EXPECT_TRUE(manager->violations().empty());
}

INSTANTIATE_TEST_SUITE_P(Formats, LibcameraAllocTest, ::testing::Values("YUYV", "NV12", "GREY"));

}  // namespace
}  // namespace omnipose
