/// (f) The per-frame path of WindowRegistration allocates nothing: after construction and
/// one warm-up frame, measure()/advance() over 50 frames perform zero heap allocations.
///
/// Every heap allocation of the process (malloc family and operator new: FFTW allocates
/// through fftwf_malloc, i.e. malloc) is counted by tests/support/allocation_counter.hpp,
/// linked into this binary only; glibc's mallinfo2 counters check the bytes in use too.

#include <gtest/gtest.h>
#include <malloc.h>

#include <cmath>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <tuple>
#include <vector>

#include "allocation_counter.hpp"
#include "omnipose/window_registration.hpp"
#include "test_images.hpp"

namespace omnipose {
namespace {

/// Two real-texture frames that differ by a shift and a small rotation, so the
/// de-rotation path runs too; synthetic texture when the photo is missing (the path under
/// test does not depend on the content).
std::pair<cv::Mat, cv::Mat> framePair() {
  cv::Mat a;
  const cv::Mat eq = test::loadEquirect(test::kPark, 1100);
  if (!eq.empty()) {
    a = test::rowBand(eq, eq.rows / 2, 110);
  } else {
    a.create(110, 1100, CV_32F);
    cv::randu(a, 0.0, 255.0);
    cv::GaussianBlur(a, a, cv::Size(0, 0), 1.5);
  }
  cv::Mat m = cv::getRotationMatrix2D(cv::Point2f(550.0f, 54.5f), 1.0, 1.01);
  m.at<double>(0, 2) += 0.7;
  cv::Mat b;
  cv::warpAffine(a, b, m, a.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT);
  return {a, b};
}

/// (worker threads, Options::noise_weighting, Options::cubic_sampling)
class WindowRegistrationRealtime
    : public ::testing::TestWithParam<std::tuple<int, bool, bool>> {};

TEST_P(WindowRegistrationRealtime, MeasureAndAdvanceAllocateNothing) {
  if (!testing::AllocationCounter::available())
    GTEST_SKIP() << "sanitizer build: the sanitizer owns malloc, allocations are not counted";
  const auto [a, b] = framePair();
  const auto [threads, noise_weighting, cubic_sampling] = GetParam();
  WindowRegistration::Options options;
  options.noise_weighting = noise_weighting;  // the noise measurement's selection too
  options.cubic_sampling = cubic_sampling;    // the de-rotation's sampler
  // 1 thread: the calling thread only; more: the worker pool.
  WindowRegistration reg(a.size(), options, threads);
  ASSERT_EQ(reg.threads(), threads);
  std::vector<WindowMotion> out(reg.windowCount());
  reg.setReference(a);
  ASSERT_TRUE(reg.measure(b, out, true));  // warm-up
  reg.advance();

  const struct mallinfo2 before = mallinfo2();
  testing::AllocationCounter counter;  // every thread: the worker pool's too
  int failures = 0, derotated = 0;
  for (int frame = 0; frame < 50; ++frame) {
    const cv::Mat& current = frame % 2 == 0 ? a : b;
    failures += !reg.measure(current, out, true);
    failures += !reg.measure(current, out, false);  // the pipeline's re-registration pass
    reg.advance();
    derotated += std::abs(out[10].rotation) > 0.005;
  }
  const std::int64_t allocations = counter.stop();
  const struct mallinfo2 after = mallinfo2();

  EXPECT_EQ(failures, 0);
  EXPECT_GT(derotated, 0) << "the de-rotation path should have run";
  EXPECT_EQ(std::isfinite(reg.noiseSigma()), noise_weighting);
  EXPECT_EQ(allocations, 0) << "heap allocations (malloc family or operator new) in the per-frame path";
  EXPECT_EQ(after.uordblks, before.uordblks) << "malloc'd bytes changed in the per-frame path";
  EXPECT_EQ(after.hblkhd, before.hblkhd) << "mmap'd bytes changed in the per-frame path";
}

INSTANTIATE_TEST_SUITE_P(Threads, WindowRegistrationRealtime,
                         ::testing::Combine(::testing::Values(1, 2, 4), ::testing::Bool(),
                                            ::testing::Bool()));

}  // namespace
}  // namespace omnipose
