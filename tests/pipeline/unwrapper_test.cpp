#include "omnipose/unwrapper.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <set>

#include <opencv2/imgproc.hpp>

#include "point_unwrap.hpp"
#include "render_fixture.hpp"

using ::testing::HasSubstr;

namespace omnipose {
namespace {

/// The indoor photo on a sphere at the identity pose through `c`: an 8-bit omni frame
/// (omni_rays x omni_rays rays per pixel) and the panorama rendered directly (float).
struct RenderedPair {
  cv::Mat omni8, pano;
};
RenderedPair renderIndoor(const Calibration& c, int omni_rays, int pano_rays) {
  const auto scene = synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kSphere);
  RenderedPair r;
  synth::Renderer(scene, c, {synth::OutputKind::kOmni, omni_rays})
      .render(Eigen::Isometry3d::Identity())
      .convertTo(r.omni8, CV_8U);
  r.pano = synth::Renderer(scene, c, {synth::OutputKind::kPanorama, pano_rays})
               .render(Eigen::Isometry3d::Identity());
  return r;
}

TEST(Unwrapper, OmniRenderUnwrapsToThePanoramaRender) {
  if (!std::filesystem::exists(testing::indoorPhoto())) GTEST_SKIP() << "missing photo";
  for (auto dir : {AzimuthDirection::kCw, AzimuthDirection::kCcw}) {
    for (auto edge : {OuterEdge::kTop, OuterEdge::kBottom}) {
      Calibration c;
      c.omni.azimuth_direction = dir;
      c.omni.outer_edge = edge;
      c.omni.azimuth_zero_deg = -20.0;
      const auto [omni8, pano] = renderIndoor(c, 3, 3);
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
  EXPECT_THAT(r.error().message(), HasSubstr("100x100, expected 720x720"));
  r = unwrapper.unwrap(cv::Mat(720, 720, CV_16UC1, cv::Scalar(50)), out);
  ASSERT_FALSE(r.has_value());
  r = unwrapper.unwrap(cv::Mat(720, 720, CV_8UC1, cv::Scalar(0)), out);
  ASSERT_FALSE(r.has_value());
  EXPECT_THAT(r.error().message(), HasSubstr("black"));
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

TEST(Unwrapper, SamplesPerAxisAreTheWholeOmniPixelsPerPanoramaPixel) {
  EXPECT_EQ(Unwrapper::samplesAlong(0.0), 1);   // no bearing
  EXPECT_EQ(Unwrapper::samplesAlong(0.7), 1);   // the omni image is coarser
  EXPECT_EQ(Unwrapper::samplesAlong(1.71), 1);  // the default lens's outer ring
  EXPECT_EQ(Unwrapper::samplesAlong(2.0), 2);
  EXPECT_EQ(Unwrapper::samplesAlong(3.4), 3);
  EXPECT_EQ(Unwrapper::samplesAlong(40.0), Unwrapper::kMaxSamplesPerAxis);
}

/// The default lens at twice the resolution: a 1440 x 1440 donut, radii 240..600 px, which
/// is 1.4..3.4 omni pixels per panorama pixel around and 3.3 across.
Calibration denseLens() {
  Calibration c;
  c.omni.image_width = c.omni.image_height = 1440;
  c.omni.center_x = c.omni.center_y = 719.5;
  c.omni.radius_inner = 240.0;
  c.omni.radius_outer = 600.0;
  return c;
}

// Where the omni image is denser than the panorama each pixel is the mean of a regular grid
// of bilinear samples over its footprint, rows by their own sample counts (the exact
// formula, on random content, including the SIMD body and the tail of every row).
TEST(Unwrapper, DenseRowsAreTheMeanOfAGridOfBilinearSamples) {
  Calibration c = denseLens();
  c.panorama.width = 1103;  // 1103 % 4 = 3
  cv::Mat grey(1440, 1440, CV_8UC1);
  cv::randu(grey, 10, 250);
  Unwrapper unwrapper(c, {});
  cv::Mat out = unwrapper.makePanorama();
  ASSERT_TRUE(unwrapper.unwrap(grey, out).has_value());
  const auto bilinear = [&](const Eigen::Vector2d& p) {
    const double x0 = std::floor(p.x()), y0 = std::floor(p.y()), ax = p.x() - x0, ay = p.y() - y0;
    const auto at = [&](double x, double y) {
      return static_cast<double>(grey.at<uint8_t>(static_cast<int>(y), static_cast<int>(x)));
    };
    return (1 - ay) * ((1 - ax) * at(x0, y0) + ax * at(x0 + 1, y0)) +
           ay * ((1 - ax) * at(x0, y0 + 1) + ax * at(x0 + 1, y0 + 1));
  };
  std::set<int> counts;
  for (int v = 0; v < out.rows; ++v) {
    double along_u = 0.0, along_v = 0.0;
    for (int u = 0; u < out.cols; ++u) {
      along_u = std::max(along_u, (c.omniPixel(u + 0.5, v) - c.omniPixel(u - 0.5, v)).norm());
      along_v = std::max(along_v, (c.omniPixel(u, v + 0.5) - c.omniPixel(u, v - 0.5)).norm());
    }
    const int su = Unwrapper::samplesAlong(along_u), sv = Unwrapper::samplesAlong(along_v);
    counts.insert(su * sv);
    for (int u = 0; u < out.cols; u += (u < out.cols - 8 ? 7 : 1)) {
      double sum = 0.0;
      for (int j = 0; j < sv; ++j)
        for (int i = 0; i < su; ++i)
          sum += bilinear(c.omniPixel(u + (i + 0.5) / su - 0.5, v + (j + 0.5) / sv - 0.5));
      EXPECT_NEAR(out.at<float>(v, u), sum / (su * sv), 2e-3) << u << "," << v;
    }
  }
  // Several sample counts: 3 across, 1..3 around.
  EXPECT_GE(counts.size(), 3u);
  EXPECT_EQ(*counts.rbegin(), 9);
}

// The exact renderer as referee: the panorama rendered directly with 4 x 4 rays per pixel
// is the area mean of the scene over each pixel. A dense omni image unwrapped with one
// bilinear sample per pixel aliases fine texture; the grid of samples comes much closer.
TEST(Unwrapper, DenseOmniImageUnwrapsCloseToTheAreaMean) {
  if (!std::filesystem::exists(testing::indoorPhoto())) GTEST_SKIP() << "missing photo";
  const Calibration c = denseLens();
  const RenderedPair r = renderIndoor(c, 2, 4);
  const cv::Mat& pano = r.pano;
  Unwrapper unwrapper(c, {});
  cv::Mat out = unwrapper.makePanorama();
  ASSERT_TRUE(unwrapper.unwrap(r.omni8, out).has_value());
  cv::Mat point;
  testing::pointSampledUnwrap(r.omni8, c).convertTo(point, CV_32F);
  const cv::Rect inner(0, 2, c.panorama.width, c.panorama.height - 4);
  const double ours = cv::mean(cv::abs(out(inner) - pano(inner)))[0];
  const double one_sample = cv::mean(cv::abs(point(inner) - pano(inner)))[0];
  std::printf("mean |unwrap - area mean|: %.3f grey levels, one sample per pixel %.3f\n", ours,
              one_sample);
  EXPECT_LT(ours, 0.5 * one_sample);  // 0.148 against 0.444
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
