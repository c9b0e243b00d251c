#include "omnipose/unwrapper.hpp"

#include <gtest/gtest.h>

#include <cmath>

#include <opencv2/imgproc.hpp>

#include "render_fixture.hpp"

namespace omnipose {
namespace {

TEST(Unwrapper, OmniRenderUnwrapsToThePanoramaRender) {
  if (!std::filesystem::exists(testing::indoorPhoto())) GTEST_SKIP() << "missing photo";
  for (auto dir : {AzimuthDirection::kCw, AzimuthDirection::kCcw}) {
    for (auto edge : {OuterEdge::kTop, OuterEdge::kBottom}) {
      Calibration c;
      c.omni.azimuth_direction = dir;
      c.omni.outer_edge = edge;
      c.omni.azimuth_zero_deg = -20.0;
      const auto scene = synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kSphere);
      synth::RenderOptions omni_options, pano_options;
      omni_options.supersample = 3;
      pano_options.output = synth::OutputKind::kPanorama;
      pano_options.supersample = 3;
      const cv::Mat omni = synth::Renderer(scene, c, omni_options).render(Eigen::Isometry3d::Identity());
      const cv::Mat pano = synth::Renderer(scene, c, pano_options).render(Eigen::Isometry3d::Identity());
      cv::Mat omni8;
      omni.convertTo(omni8, CV_8U);
      Unwrapper unwrapper(c, {});
      cv::Mat out = unwrapper.makePanorama();
      ASSERT_TRUE(unwrapper.unwrap(omni8, out).has_value());
      // The omni image has fewer pixels per degree near the inner ring, so the two differ
      // by resampling blur, not by geometry: compare after a light blur of both.
      cv::Mat a, b;
      cv::GaussianBlur(out, a, cv::Size(0, 0), 1.5);
      cv::GaussianBlur(pano, b, cv::Size(0, 0), 1.5);
      const cv::Rect inner(0, 3, c.panorama.width, c.panorama.height - 6);
      const double mad = cv::mean(cv::abs(a(inner) - b(inner)))[0];
      EXPECT_LT(mad, 3.0) << "mean abs difference " << mad << " grey levels";
      // A geometric mistake (mirrored azimuth or flipped rows) would differ by far more.
      cv::Mat flipped;
      cv::flip(b, flipped, 0);
      EXPECT_GT(cv::mean(cv::abs(a(inner) - flipped(inner)))[0], 3 * mad);
    }
  }
}

TEST(Unwrapper, RejectsWrongSizeTypeAndBlackFramesWithAClearMessage) {
  Calibration c;
  Unwrapper unwrapper(c, {});
  cv::Mat out = unwrapper.makePanorama();
  auto r = unwrapper.unwrap(cv::Mat(100, 100, CV_8UC1, cv::Scalar(50)), out);
  ASSERT_FALSE(r.has_value());
  EXPECT_EQ(r.error().code(), ErrorCode::kBadFrame);
  EXPECT_NE(r.error().message().find("100x100, expected 720x720"), std::string_view::npos);
  r = unwrapper.unwrap(cv::Mat(720, 720, CV_16UC1, cv::Scalar(50)), out);
  ASSERT_FALSE(r.has_value());
  r = unwrapper.unwrap(cv::Mat(720, 720, CV_8UC1, cv::Scalar(0)), out);
  ASSERT_FALSE(r.has_value());
  EXPECT_NE(r.error().message().find("black"), std::string_view::npos);
  cv::Mat small_out(10, 10, CV_32FC1);
  r = unwrapper.unwrap(cv::Mat(720, 720, CV_8UC1, cv::Scalar(50)), small_out);
  ASSERT_FALSE(r.has_value());
  EXPECT_EQ(r.error().code(), ErrorCode::kInvalidArgument);
}

TEST(Unwrapper, ColourAndGreyGiveTheSamePanoramaAndTableMatchesTheFormula) {
  Calibration c;
  cv::Mat grey(720, 720, CV_8UC1);
  cv::randu(grey, 10, 250);
  cv::Mat bgr;
  cv::cvtColor(grey, bgr, cv::COLOR_GRAY2BGR);
  Unwrapper unwrapper(c, {});
  cv::Mat a = unwrapper.makePanorama(), b = unwrapper.makePanorama();
  ASSERT_TRUE(unwrapper.unwrap(grey, a).has_value());
  ASSERT_TRUE(unwrapper.unwrap(bgr, b).has_value());
  EXPECT_LT(cv::norm(a, b, cv::NORM_INF), 1e-3);
  // Spot-check the table against omniPixel with OpenCV's bilinear sampler.
  cv::Mat grey_f;
  grey.convertTo(grey_f, CV_32F);
  for (int v : {0, 37, 109}) {
    for (int u : {0, 275, 1099}) {
      const Eigen::Vector2d p = c.omniPixel(u, v);
      cv::Mat patch;
      cv::getRectSubPix(grey_f, cv::Size(1, 1), cv::Point2f(p.x(), p.y()), patch);
      EXPECT_NEAR(a.at<float>(v, u), patch.at<float>(0, 0), 0.05) << u << "," << v;
    }
  }
}

// Every pixel, including the last W % 4 columns (the lookup runs four at a time) and pixels
// whose footprint leaves the frame (black, unusable), against bilinear interpolation at
// the calibration's omniPixel().
TEST(Unwrapper, EveryPixelIsTheBilinearSampleOrBlackOutsideTheFrame) {
  Calibration c;
  c.panorama.width = 1103;  // 1103 % 4 = 3
  c.omni.center_x = 120.0;  // the outer ring leaves the frame on the left
  cv::Mat grey(720, 720, CV_8UC1);
  cv::randu(grey, 10, 250);
  Unwrapper unwrapper(c, {});
  cv::Mat out = unwrapper.makePanorama();
  ASSERT_TRUE(unwrapper.unwrap(grey, out).has_value());
  int outside = 0, tail = 0;
  for (int v = 0; v < out.rows; ++v) {
    for (int u = 0; u < out.cols; ++u) {
      const Eigen::Vector2d p = c.omniPixel(u, v);
      const double x0 = std::floor(p.x()), y0 = std::floor(p.y());
      const bool inside = x0 >= 0 && y0 >= 0 && x0 + 1 < grey.cols && y0 + 1 < grey.rows;
      EXPECT_EQ(unwrapper.validity().at<float>(v, u), inside ? 1.0f : 0.0f) << u << "," << v;
      if (!inside) {
        ++outside;
        EXPECT_EQ(out.at<float>(v, u), 0.0f) << u << "," << v;
        continue;
      }
      const auto at = [&](double x, double y) {
        return static_cast<double>(grey.at<uint8_t>(static_cast<int>(y), static_cast<int>(x)));
      };
      const double ax = p.x() - x0, ay = p.y() - y0;
      const double expected =
          (1 - ay) * ((1 - ax) * at(x0, y0) + ax * at(x0 + 1, y0)) +
          ay * ((1 - ax) * at(x0, y0 + 1) + ax * at(x0 + 1, y0 + 1));
      EXPECT_NEAR(out.at<float>(v, u), expected, 1e-3) << u << "," << v;
      if (u >= out.cols - out.cols % 4) ++tail;
    }
  }
  EXPECT_GT(outside, 1000);
  EXPECT_GT(tail, 100);
}

TEST(Unwrapper, PanoramaInputPassesThrough) {
  Calibration c;
  Unwrapper::Options o;
  o.input = InputKind::kPanorama;
  Unwrapper unwrapper(c, o);
  EXPECT_EQ(unwrapper.inputSize(), cv::Size(1100, 110));
  cv::Mat pano(110, 1100, CV_8UC1);
  cv::randu(pano, 0, 255);
  cv::Mat out = unwrapper.makePanorama();
  ASSERT_TRUE(unwrapper.unwrap(pano, out).has_value());
  cv::Mat expected;
  pano.convertTo(expected, CV_32F);
  EXPECT_EQ(cv::norm(out, expected, cv::NORM_INF), 0.0);
}

// toGrey() + unwrapRows() over any split of the rows (as the pipeline runs them on its
// pool) write exactly what unwrap() writes, for omni and panorama input, grey and colour;
// toGrey() refuses what unwrap() refuses.
TEST(Unwrapper, RowBandsGiveExactlyWhatUnwrapGives) {
  Calibration c;
  for (const InputKind input : {InputKind::kOmni, InputKind::kPanorama}) {
    Unwrapper::Options o;
    o.input = input;
    Unwrapper unwrapper(c, o);
    cv::Mat grey(unwrapper.inputSize(), CV_8UC1);
    cv::randu(grey, 10, 250);
    cv::Mat bgr;
    cv::cvtColor(grey, bgr, cv::COLOR_GRAY2BGR);
    for (const cv::Mat& frame : {grey, bgr}) {
      cv::Mat whole = unwrapper.makePanorama();
      ASSERT_TRUE(unwrapper.unwrap(frame, whole).has_value());
      for (const int bands : {1, 3, 8, 110}) {
        cv::Mat banded(whole.size(), CV_32FC1, cv::Scalar(-1.0f));
        const auto source = unwrapper.toGrey(frame);
        ASSERT_TRUE(source.has_value());
        const int rows = banded.rows;
        for (int b = bands - 1; b >= 0; --b)  // any order
          unwrapper.unwrapRows(**source, banded, b * rows / bands, (b + 1) * rows / bands);
        EXPECT_EQ(cv::norm(banded, whole, cv::NORM_INF), 0.0)
            << "input " << static_cast<int>(input) << ", " << frame.channels() << " channels, "
            << bands << " bands";
      }
    }
    const auto black = unwrapper.toGrey(cv::Mat(unwrapper.inputSize(), CV_8UC1, cv::Scalar(0)));
    ASSERT_FALSE(black.has_value());
    EXPECT_EQ(black.error().code(), ErrorCode::kBadFrame);
    EXPECT_FALSE(unwrapper.toGrey(cv::Mat(5, 5, CV_8UC1, cv::Scalar(50))).has_value());
  }
}

}  // namespace
}  // namespace omnipose
