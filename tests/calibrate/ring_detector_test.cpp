// Ring detection on omni images rendered by the exact renderer with a known calibration:
// centres off the image centre, several radii, both directions and outer edges, a ring cut
// by the image border, noise and blur. Issue 6: centre within 1 px, radii within 2 px.

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "omnipose/calibrate/ring_detector.hpp"
#include "synthetic.hpp"
#include "test_figures.hpp"

namespace omnipose::calibrate {
namespace {

using namespace omnipose::calibrate::testing;  // synthetic.hpp
using omnipose::testing::recordFigure;

constexpr double kCentreTolerance = 1.0;  ///< pixels
constexpr double kRadiusTolerance = 2.0;  ///< pixels

struct Case {
  const char* name;
  Calibration cal;
  double noise = 0.0;
  double blur = 0.0;
};

std::vector<Case> cases() {
  using D = AzimuthDirection;
  using E = OuterEdge;
  return {
      {"ccw_bottom_right_low", makeCalibration(800, 640, 371.3, 338.7, 97.0, 268.0, 30, D::kCcw, E::kBottom)},
      {"cw_top_right_high", makeCalibration(800, 640, 402.6, 297.2, 83.5, 241.3, -75, D::kCw, E::kTop)},
      {"cw_bottom_noisy_blurred", makeCalibration(720, 720, 330.8, 391.4, 140.2, 300.6, 200, D::kCw, E::kBottom), 3.0, 1.0},
      {"ccw_top_cut_by_border", makeCalibration(640, 480, 318.4, 236.9, 105.0, 262.0, 90, D::kCcw, E::kTop)},
      {"cw_top_small_inner", makeCalibration(480, 400, 251.2, 190.6, 48.0, 170.0, 0, D::kCw, E::kTop)},
  };
}

class RingDetectorRendered : public ::testing::TestWithParam<Case> {};

TEST_P(RingDetectorRendered, RecoversCentreAndRadii) {
  const Case& c = GetParam();
  const cv::Mat img = renderOmni(kIndoor, c.cal, 0.0, c.noise, c.blur);
  const auto det = detectRing(img, {});
  ASSERT_TRUE(det) << det.error().c_str();
  const Eigen::Vector2d truth(c.cal.omni.center_x, c.cal.omni.center_y);
  const double dc = (det->center - truth).norm();
  const double di = det->radius_inner - c.cal.omni.radius_inner;
  const double dout = det->radius_outer - c.cal.omni.radius_outer;
  recordFigure("centre_error_px", dc, 3);
  recordFigure("inner_edge_error_px", di, 3);
  recordFigure("outer_edge_error_px", dout, 3);
  recordFigure("edge_fit_rms_px", det->rms, 2);
  EXPECT_LT(dc, kCentreTolerance) << "centre error, px";
  EXPECT_LT(std::abs(di), kRadiusTolerance) << "inner edge error " << di << " px";
  EXPECT_LT(std::abs(dout), kRadiusTolerance) << "outer edge error " << dout << " px";
  // The independent fits of the two edges agree with the truth too.
  EXPECT_LT((det->inner.circle.center - truth).norm(), kCentreTolerance);
  EXPECT_LT((det->outer.circle.center - truth).norm(), kCentreTolerance);
  // Nothing here is a stacked lens-body edge.
  EXPECT_EQ(det->inner.stacked, 0);
  EXPECT_EQ(det->outer.stacked, 0);
  // Dark centre -> scene -> dark housing.
  EXPECT_EQ(det->inner.polarity, +1);
  EXPECT_EQ(det->outer.polarity, -1);
}

TEST_P(RingDetectorRendered, SeveralFramesAgree) {
  const Case& c = GetParam();
  std::vector<cv::Mat> frames = {renderOmni(kIndoor, c.cal, 0.0, c.noise, c.blur),
                                 renderOmni(kIndoor, c.cal, 25.0, c.noise, c.blur)};
  const auto multi = detectRings(frames, {});
  ASSERT_TRUE(multi.estimate);
  ASSERT_EQ(multi.detections.size(), 2u);
  const auto& e = *multi.estimate;
  EXPECT_EQ(e.frames, 2);
  EXPECT_LT((e.center - Eigen::Vector2d(c.cal.omni.center_x, c.cal.omni.center_y)).norm(),
            kCentreTolerance);
  EXPECT_LT(std::abs(e.radius_inner - c.cal.omni.radius_inner), kRadiusTolerance);
  EXPECT_LT(std::abs(e.radius_outer - c.cal.omni.radius_outer), kRadiusTolerance);
  EXPECT_LT(e.center_spread, 0.5);
  EXPECT_GT(e.edge_width_inner, 0.0);
}

INSTANTIATE_TEST_SUITE_P(Calibrations, RingDetectorRendered, ::testing::ValuesIn(cases()),
                         [](const auto& info) { return std::string(info.param.name); });

TEST(RingDetector, VotedCentreIsCloseEnoughToStart) {
  const auto cal = makeCalibration(800, 640, 402.6, 297.2, 83.5, 241.3, 0, AzimuthDirection::kCw,
                                   OuterEdge::kTop);
  const cv::Mat img = renderOmni(kIndoor, cal, 0.0);
  const Eigen::Vector2d c = voteCenter(toGreyFloat(img), 480);
  EXPECT_LT((c - Eigen::Vector2d(402.6, 297.2)).norm(), 4.0);
}

/// Paints a bright bezel (grey 230) from r_in - 2 to r_in + width (over the dark centre's
/// edge and the scene), anti-aliased by 4 x 4 supersampling: a dark -> bright lens-body edge
/// followed by a second concentric edge where the scene now begins, like a phone camera's
/// reflection with its bezel.
cv::Mat withBezel(const cv::Mat& img, const OmniLens& lens, double width) {
  cv::Mat out;
  img.convertTo(out, CV_32F);
  for (int y = 0; y < out.rows; ++y)
    for (int x = 0; x < out.cols; ++x) {
      int inside = 0;
      for (int sy = 0; sy < 4; ++sy)
        for (int sx = 0; sx < 4; ++sx) {
          const double r = std::hypot(x + (sx + 0.5) / 4 - 0.5 - lens.center_x,
                                      y + (sy + 0.5) / 4 - 0.5 - lens.center_y);
          inside += r >= lens.radius_inner - 2.0 && r < lens.radius_inner + width;
        }
      const float f = inside / 16.0f;
      out.at<float>(y, x) = (1 - f) * out.at<float>(y, x) + f * 230.0f;
    }
  out.convertTo(out, CV_8U);
  return out;
}

TEST(RingDetector, MovesPastAStackedBezelEdge) {
  const auto cal = makeCalibration(800, 640, 371.3, 338.7, 97.0, 268.0, 30,
                                   AzimuthDirection::kCcw, OuterEdge::kBottom);
  const double bezel = 7.0;
  const cv::Mat img = withBezel(renderOmni(kIndoor, cal, 0.0), cal.omni, bezel);
  const auto det = detectRing(img, {});
  ASSERT_TRUE(det) << det.error().c_str();
  recordFigure("inner_radius_px", det->radius_inner, 2);
  recordFigure("first_inner_edge_radius_px", det->inner.first_radius, 2);
  RecordProperty("stacked_inner_edges", det->inner.stacked);
  recordFigure("outer_radius_px", det->radius_outer, 2);
  // The scene starts at the bezel's outer edge; the strongest edge is the bezel's inner one.
  EXPECT_NEAR(det->radius_inner, cal.omni.radius_inner + bezel, kRadiusTolerance);
  EXPECT_EQ(det->inner.stacked, 1);
  EXPECT_NEAR(det->inner.first_radius, cal.omni.radius_inner - 2.0, kRadiusTolerance);
  EXPECT_NEAR(det->radius_outer, cal.omni.radius_outer, kRadiusTolerance);
  EXPECT_LT((det->center - Eigen::Vector2d(371.3, 338.7)).norm(), kCentreTolerance);

  // With step 6 off the detector stops at whichever edge it found first; with it on it
  // always ends at the last one.
  RingDetectorOptions off;
  off.stacked_edges = false;
  const auto plain = detectRing(img, off);
  ASSERT_TRUE(plain);
  EXPECT_LE(plain->radius_inner, det->radius_inner + 0.5);
}

TEST(RingDetector, RejectsAnImageWithoutRing) {
  cv::Mat flat(300, 400, CV_8UC1, cv::Scalar(90));
  const auto det = detectRing(flat, {});
  ASSERT_FALSE(det);
  EXPECT_EQ(det.error().code(), ErrorCode::kIllConditioned);
  RingDetectorOptions bad;
  bad.rays = 3;
  const auto invalid = detectRing(flat, bad);
  ASSERT_FALSE(invalid);
  EXPECT_EQ(invalid.error().code(), ErrorCode::kInvalidArgument);
}

TEST(RingDetector, CombineTakesTheMedianAndReportsTheSpread) {
  std::vector<RingDetection> d(3);
  const double xs[3] = {100.0, 101.0, 104.0};
  for (int k = 0; k < 3; ++k) {
    d[k].center = {xs[k], 50.0};
    d[k].radius_inner = 20.0 + k;
    d[k].radius_outer = 80.0;
  }
  const auto e = combineDetections(d);
  EXPECT_DOUBLE_EQ(e.center.x(), 101.0);
  EXPECT_DOUBLE_EQ(e.radius_inner, 21.0);
  EXPECT_DOUBLE_EQ(e.center_spread, 3.0);
  EXPECT_DOUBLE_EQ(e.inner_spread, 1.0);
  EXPECT_THROW(combineDetections({}), std::invalid_argument);
}

}  // namespace
}  // namespace omnipose::calibrate
