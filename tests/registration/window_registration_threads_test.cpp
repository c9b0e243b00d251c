// WindowRegistration gives the same bits for any number of worker threads.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstring>
#include <stdexcept>
#include <string>
#include <opencv2/imgproc.hpp>

#include "omnipose/window_registration.hpp"
#include "test_images.hpp"

using ::testing::HasSubstr;

namespace omnipose {
namespace {

cv::Mat texture() {
  const cv::Mat eq = test::loadEquirect(test::kIndoor, 1100);
  if (!eq.empty()) return test::rowBand(eq, eq.rows / 2, 110);
  cv::Mat a(110, 1100, CV_32F);
  cv::randu(a, 0.0, 255.0);
  cv::GaussianBlur(a, a, cv::Size(0, 0), 1.5);
  return a;
}

/// Reference, then two frames measured (kept and not kept), one advance: every motion.
/// With a validity map, the masked windows take the direct FFT and the others the shared
/// column stage.
std::vector<double> trace(int threads, const cv::Mat& a, const cv::Mat& b, const cv::Mat& c,
                          const cv::Mat& validity = cv::Mat()) {
  WindowRegistration::Options o;
  WindowRegistration reg(a.size(), o, threads);
  EXPECT_EQ(reg.threads(), threads);
  if (!validity.empty()) reg.setValidity(validity);
  std::vector<WindowMotion> out(reg.windowCount());
  std::vector<double> t;
  auto record = [&] {
    for (const WindowMotion& w : out)
      for (double x : {w.center_u, w.du, w.dv, w.rotation, w.scale, w.confidence,
                       w.rs_confidence, w.valid ? 1.0 : 0.0})
        t.push_back(x);
  };
  reg.setReference(a);
  EXPECT_TRUE(reg.measure(b, out, true));
  record();
  EXPECT_TRUE(reg.measure(c, out, false));
  record();
  EXPECT_TRUE(reg.measure(c, out, false, out));  // known rotation/scale (shift-only path)
  record();
  reg.advance();
  EXPECT_TRUE(reg.measure(c, out, true));
  record();
  return t;
}

TEST(WindowRegistrationThreads, ResultIsBitIdenticalForAnyThreadCount) {
  const cv::Mat a = texture();
  cv::Mat b, c;
  cv::Mat m = cv::getRotationMatrix2D(cv::Point2f(550.0f, 54.5f), 1.5, 1.01);
  m.at<double>(0, 2) += 0.7;
  cv::warpAffine(a, b, m, a.size(), cv::INTER_CUBIC, cv::BORDER_REFLECT);
  m = cv::getRotationMatrix2D(cv::Point2f(550.0f, 54.5f), -0.8, 0.995);
  m.at<double>(1, 2) -= 1.3;
  cv::warpAffine(a, c, m, a.size(), cv::INTER_CUBIC, cv::BORDER_REFLECT);

  // A mast-like masked block: some windows masked, some partly, the rest plain.
  cv::Mat validity(a.size(), CV_32F, cv::Scalar(1.0f));
  validity(cv::Rect(400, 30, 60, 80)).setTo(0.0f);
  for (const cv::Mat& mask : {cv::Mat(), validity}) {
    SCOPED_TRACE(mask.empty() ? "no mask" : "masked block");
    const std::vector<double> one = trace(1, a, b, c, mask);
    int valid = 0;
    for (std::size_t i = 7; i < one.size(); i += 8) valid += one[i] > 0.0;
    ASSERT_GT(valid, 100) << "too few valid windows for a meaningful comparison";
    for (int threads : {2, 4, 7}) {
      const std::vector<double> many = trace(threads, a, b, c, mask);
      ASSERT_EQ(many.size(), one.size());
      EXPECT_EQ(std::memcmp(many.data(), one.data(), one.size() * sizeof(double)), 0)
          << threads << " threads: results differ from 1 thread";
    }
  }
}

TEST(WindowRegistrationThreads, ThreadCountIsValidated) {
  const WindowRegistration::Options o;
  for (int threads : {-1, WindowRegistration::kMaxThreads + 1}) {
    try {
      WindowRegistration reg(cv::Size(1100, 110), o, threads);
      ADD_FAILURE() << threads << " threads accepted";
    } catch (const std::invalid_argument& e) {
      EXPECT_THAT(e.what(),
                  HasSubstr("threads: " + std::to_string(threads) +
                            " is outside [0, 256] (0 = all online cores)"));
    }
  }
  WindowRegistration reg(cv::Size(1100, 110), o, 0);  // every online core
  EXPECT_GE(reg.threads(), 1);
}

}  // namespace
}  // namespace omnipose
