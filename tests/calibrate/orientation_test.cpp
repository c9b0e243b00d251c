// Orientation values of the calibration: the column-shift sign (DESIGN.md section 2), the
// azimuth direction from a rendered turn-left sequence, the outer edge from the vertical
// appearance cue.

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <random>

#include "omnipose/calibrate/orientation.hpp"
#include "synthetic.hpp"

namespace omnipose::calibrate {
namespace {

using namespace omnipose::calibrate::testing;  // synthetic.hpp

cv::Mat randomPanorama(int w, int h, std::uint64_t seed) {
  cv::Mat p(h, w, CV_32FC1);
  cv::RNG rng(seed);
  rng.fill(p, cv::RNG::UNIFORM, 0, 255);
  cv::GaussianBlur(p, p, {0, 0}, 2.0);
  return p;
}

/// current(u) = previous(u + du) (periodic, linear interpolation): content at u in the
/// current panorama appears at u + du in the previous one.
cv::Mat shifted(const cv::Mat& previous, double du) {
  cv::Mat cur(previous.size(), CV_32FC1);
  const int w = previous.cols;
  for (int v = 0; v < previous.rows; ++v)
    for (int u = 0; u < w; ++u) {
      const double s = u + du;
      const double f = std::floor(s);
      const int a = ((static_cast<int>(f) % w) + w) % w, b = (a + 1) % w;
      const double t = s - f;
      cur.at<float>(v, u) =
          static_cast<float>((1 - t) * previous.at<float>(v, a) + t * previous.at<float>(v, b));
    }
  return cur;
}

TEST(ColumnShift, SignFollowsTheDesignConvention) {
  const cv::Mat prev = randomPanorama(360, 40, 1);
  for (double du : {7.0, -12.0, 3.5, 150.0}) {
    const auto s = columnShift(prev, shifted(prev, du));
    ASSERT_TRUE(s);
    EXPECT_NEAR(s->du, du, 0.15) << du;
    EXPECT_GT(s->peak_ratio, 2.0);
  }
}

TEST(ColumnShift, AgreesWithPhaseCorrelateOfCurrentAgainstPrevious) {
  // DESIGN.md section 2: cv::phaseCorrelate(current, previous) returns (du, dv).
  const cv::Mat prev = randomPanorama(256, 64, 2);
  const cv::Mat cur = shifted(prev, 9.0);
  const cv::Point2d pc = cv::phaseCorrelate(cur, prev);
  const auto s = columnShift(prev, cur);
  ASSERT_TRUE(s);
  EXPECT_NEAR(pc.x, 9.0, 0.3);
  EXPECT_NEAR(s->du, pc.x, 0.3);
}

TEST(ColumnShift, RejectsMismatchedSizes) {
  EXPECT_FALSE(columnShift(cv::Mat::zeros(10, 20, CV_32F), cv::Mat::zeros(10, 21, CV_32F)));
}

class TurnLeft : public ::testing::TestWithParam<std::tuple<AzimuthDirection, OuterEdge>> {};

TEST_P(TurnLeft, GivesTheDirectionOfTheRenderer) {
  const auto [dir, edge] = GetParam();
  const auto cal = makeCalibration(640, 560, 331.4, 268.9, 70.0, 230.0, 40, dir, edge);
  // The robot turns left (positive yaw) by 4 degrees per frame.
  std::vector<cv::Mat> frames;
  for (int k = 0; k < 3; ++k) frames.push_back(renderOmni(kIndoor, cal, 4.0 * k));
  Calibration unknown = cal;  // what the tool knows when it measures the direction
  unknown.omni.azimuth_direction = AzimuthDirection::kCw;
  unknown.omni.azimuth_zero_deg = 0.0;
  const auto res = directionFromTurnLeft(frames, unknown);
  EXPECT_TRUE(res.decisive) << res.how;
  EXPECT_EQ(res.direction, dir) << res.how;
  ASSERT_EQ(res.shifts.size(), 2u);
  // Each pair turned 4 degrees: |du| * gamma = 4 deg.
  for (const auto& s : res.shifts) EXPECT_NEAR(std::abs(s.du) * 360.0 / 1100.0, 4.0, 0.2);
  EXPECT_NEAR(res.total_yaw_deg, 8.0, 0.3);

  // Told that a right turn is a left turn, it must choose the other direction.
  std::vector<cv::Mat> reversed(frames.rbegin(), frames.rend());
  const auto wrong = directionFromTurnLeft(reversed, unknown);
  EXPECT_NE(wrong.direction, dir);
}

INSTANTIATE_TEST_SUITE_P(
    DirectionsAndEdges, TurnLeft,
    ::testing::Combine(::testing::Values(AzimuthDirection::kCw, AzimuthDirection::kCcw),
                       ::testing::Values(OuterEdge::kTop, OuterEdge::kBottom)),
    [](const auto& info) {
      return std::string(std::get<0>(info.param) == AzimuthDirection::kCw ? "cw" : "ccw") +
             (std::get<1>(info.param) == OuterEdge::kTop ? "_top" : "_bottom");
    });

TEST(TurnLeft, NoMotionIsNotDecisive) {
  const auto cal = makeCalibration(640, 560, 331.4, 268.9, 70.0, 230.0, 0, AzimuthDirection::kCcw,
                                   OuterEdge::kTop);
  const cv::Mat f = renderOmni(kIndoor, cal, 0.0);
  const std::vector<cv::Mat> frames = {f, f, f};
  const auto res = directionFromTurnLeft(frames, cal);
  EXPECT_FALSE(res.decisive);
  EXPECT_THROW(directionFromTurnLeft(std::span<const cv::Mat>(frames.data(), 1), cal),
               std::invalid_argument);
}

TEST(UpCue, BrightSkyDecidesTheOuterEdge) {
  if (!std::filesystem::exists(kPark)) GTEST_SKIP() << "no park texture at " << kPark;
  // A tall panorama (H = 400 of W = 1100: about +-48 degrees) so the ring sees sky and grass.
  for (OuterEdge edge : {OuterEdge::kTop, OuterEdge::kBottom}) {
    const auto cal = makeCalibration(640, 560, 331.4, 268.9, 60.0, 240.0, 0,
                                     AzimuthDirection::kCw, edge, 400);
    const std::vector<cv::Mat> frames = {renderOmni(kPark, cal, 0.0)};
    const auto other = edge == OuterEdge::kTop ? OuterEdge::kBottom : OuterEdge::kTop;
    const auto res = outerEdgeFromAppearance(frames, cal.omni, UpCue::kBright, other);
    EXPECT_TRUE(res.decisive) << res.how;
    EXPECT_EQ(res.edge, edge) << res.how;
    // The dark cue says the opposite.
    const auto dark = outerEdgeFromAppearance(frames, cal.omni, UpCue::kDark, edge);
    EXPECT_EQ(dark.edge, other) << dark.how;
  }
}

TEST(UpCue, NoneAndUndecidedUseTheFallback) {
  const auto cal = makeCalibration(640, 560, 331.4, 268.9, 60.0, 240.0, 0, AzimuthDirection::kCw,
                                   OuterEdge::kTop);
  // A ring of uniform brightness has no vertical cue.
  cv::Mat flat(560, 640, CV_8UC1, cv::Scalar(120));
  const std::vector<cv::Mat> frames = {flat};
  const auto res = outerEdgeFromAppearance(frames, cal.omni, UpCue::kBright, OuterEdge::kBottom);
  EXPECT_FALSE(res.decisive);
  EXPECT_EQ(res.edge, OuterEdge::kBottom);
  const auto none = outerEdgeFromAppearance(frames, cal.omni, UpCue::kNone, OuterEdge::kTop);
  EXPECT_FALSE(none.decisive);
  EXPECT_EQ(none.edge, OuterEdge::kTop);
  EXPECT_EQ(parseUpCue("dark"), UpCue::kDark);
  EXPECT_THROW(parseUpCue("sky"), std::invalid_argument);
}

TEST(Orientation, ImageAngleAndAssumedDirection) {
  OmniLens lens;
  lens.center_x = 100;
  lens.center_y = 100;
  EXPECT_NEAR(imageAngleDeg(lens, {200, 100}), 0.0, 1e-12);
  EXPECT_NEAR(imageAngleDeg(lens, {100, 200}), 90.0, 1e-12);   // image y down: clockwise
  EXPECT_NEAR(imageAngleDeg(lens, {100, 0}), 270.0, 1e-12);
  EXPECT_EQ(assumedDirection(OuterEdge::kTop), AzimuthDirection::kCw);
  EXPECT_EQ(assumedDirection(OuterEdge::kBottom), AzimuthDirection::kCcw);
}

}  // namespace
}  // namespace omnipose::calibrate
