// The calibration tool on the real images of ../shared/data (skipped where that folder is
// absent; the Kogeto frames are GPL-3.0 and are not part of the repository).
//
// No ground truth: the checks are plausibility (the README's by-eye numbers, the OCamCalib
// reference of the mirror image), repeatability between frames, the concentricity of the
// independently fitted edges, and what was verified by looking at the previews (people and
// text upright with the chosen outer_edge).

#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "omnipose/calibrate/lens_calibrator.hpp"
#include "omnipose/calibrate/preview.hpp"
#include "test_figures.hpp"

namespace omnipose::calibrate {
namespace {

const std::filesystem::path kData =
    std::filesystem::path(OMNIPOSE_SOURCE_DIR) / ".." / "shared" / "data";

std::vector<cv::Mat> load(const std::vector<std::filesystem::path>& files) {
  std::vector<cv::Mat> out;
  for (const auto& f : files) {
    out.push_back(cv::imread(f.string(), cv::IMREAD_COLOR));
    if (out.back().empty()) ADD_FAILURE() << "cannot read " << f;
  }
  return out;
}

TEST(RealKogetoDot, FindsPlausibleCirclesAndTheVertical) {
  const auto a = kData / "kogeto_dot/frame_a.png", b = kData / "kogeto_dot/frame_b.png";
  if (!std::filesystem::exists(a) || !std::filesystem::exists(b))
    GTEST_SKIP() << "Kogeto Dot frames not found under " << kData << " (not in the repository)";
  const auto frames = load({a, b});
  const auto res = calibrateLens(frames, {});
  std::fputs(res.report().c_str(), stdout);
  ASSERT_TRUE(res.ring);
  ASSERT_EQ(res.detections.size(), 2u);
  const auto& c = res.calibration.omni;
  // data/README.md, read by eye: donut near (286, 470), radii about 110 and 230 px.
  EXPECT_LT((res.ring->center - Eigen::Vector2d(286, 470)).norm(), 15.0);
  EXPECT_NEAR(res.ring->radius_inner, 110.0, 10.0);
  EXPECT_NEAR(res.ring->radius_outer, 230.0, 10.0);
  // The lens does not move against the phone: both frames give the same circles.
  EXPECT_LT(res.ring->center_spread, 1.0);
  EXPECT_LT(res.ring->inner_spread, 1.0);
  EXPECT_LT(res.ring->outer_spread, 1.0);
  // The independently fitted edge circles are concentric.
  for (const auto& d : res.detections)
    EXPECT_LT((d.inner.circle.center - d.outer.circle.center).norm(), 2.0);
  // The ceiling and its lights are next to the dark centre: the outer ring looks down
  // (checked on the preview: people and the banner text stand upright with `bottom`).
  ASSERT_TRUE(res.outer_edge);
  EXPECT_TRUE(res.outer_edge->decisive) << res.outer_edge->how;
  EXPECT_EQ(c.outer_edge, OuterEdge::kBottom);
  // frame_a -> frame_b: the static scene did not turn (only people moved): the replayed
  // rotation is small about every axis.
  ASSERT_EQ(res.motions.size(), 1u);
  ASSERT_TRUE(res.motions[0].ok) << res.motions[0].error;
  EXPECT_LT(res.motions[0].omega_deg.norm(), 0.5);
  EXPECT_LT(std::abs(res.motions[0].column_shift_deg), 0.5);
  // The preview can be drawn.
  const auto lines = res.summaryLines();
  const cv::Mat preview = renderPreview(frames, res.calibration, &res.detections[0], lines);
  EXPECT_GT(preview.cols, 0);
}

TEST(RealKogetoDot, ARotatedFrameIsAPureYawOfTheMeasuredSign) {
  // frame_a -> frame_b did not turn, so make a turn: rotating the donut about the lens
  // centre is a pure yaw for the calibration's model. On screen counter-clockwise by alpha
  // moves content to smaller image angles a; with cw (a = a0 + theta) that is theta_cur =
  // theta_prev - alpha, a left turn by alpha (DESIGN.md section 2).
  const auto a = kData / "kogeto_dot/frame_a.png";
  if (!std::filesystem::exists(a)) GTEST_SKIP() << "Kogeto Dot frames not found under " << kData;
  const cv::Mat frame = cv::imread(a.string(), cv::IMREAD_COLOR);
  LensCalibratorOptions first;
  first.replay = false;
  const auto ring = calibrateLens(std::vector<cv::Mat>{frame}, first).calibration.omni;
  const double alpha = 6.0;
  for (double sign : {+1.0, -1.0}) {
    cv::Mat turned;
    const cv::Mat rot = cv::getRotationMatrix2D(
        cv::Point2f(static_cast<float>(ring.center_x), static_cast<float>(ring.center_y)),
        sign * alpha, 1.0);
    cv::warpAffine(frame, turned, rot, frame.size(), cv::INTER_CUBIC, cv::BORDER_REPLICATE);
    LensCalibratorOptions o;
    o.turn_left = true;
    const auto res = calibrateLens(std::vector<cv::Mat>{frame, turned}, o);
    ASSERT_TRUE(res.direction);
    EXPECT_TRUE(res.direction->decisive) << res.direction->how;
    EXPECT_EQ(res.calibration.omni.azimuth_direction,
              sign > 0 ? AzimuthDirection::kCw : AzimuthDirection::kCcw)
        << res.direction->how;
    ASSERT_EQ(res.motions.size(), 1u);
    ASSERT_TRUE(res.motions[0].ok) << res.motions[0].error;
    const std::string turn = sign > 0 ? "ccw" : "cw";  // on screen
    testing::recordFigure("rotated_" + turn + "_roll_deg", res.motions[0].omega_deg.x(), 2);
    testing::recordFigure("rotated_" + turn + "_pitch_deg", res.motions[0].omega_deg.y(), 2);
    testing::recordFigure("rotated_" + turn + "_yaw_deg", res.motions[0].omega_deg.z(), 2);
    SCOPED_TRACE("rotated " + testing::fixed(sign * alpha, 0) + " deg on screen");
    EXPECT_NEAR(res.motions[0].omega_deg.z(), alpha, 0.3);
    EXPECT_LT(std::abs(res.motions[0].omega_deg.x()), 0.3);
    EXPECT_LT(std::abs(res.motions[0].omega_deg.y()), 0.3);
  }
}

TEST(RealMirror, AgreesWithTheOCamCalibReference) {
  const auto img = kData / "catadioptric/mirror_office_1920x1080.jpg";
  if (!std::filesystem::exists(img)) GTEST_SKIP() << "mirror image not found under " << kData;
  const auto frames = load({img});
  LensCalibratorOptions o;
  o.replay = false;
  const auto res = calibrateLens(frames, o);
  std::fputs(res.report().c_str(), stdout);
  ASSERT_TRUE(res.ring);
  // OCamCalib: centre row 545.87, column 674.32 in a crop that removed 300 px on the left,
  // i.e. (974.32, 545.87) in the full 1920 x 1080 frame; ROI radii 235 .. 600 px. The OCamCalib
  // centre is the projection model's optical centre, not the rim's: they need not coincide
  // (here they differ by about 10 px; the fitted circles lie on the visible edges).
  const Eigen::Vector2d ocam(674.318875 + 300.0, 545.872616);
  EXPECT_LT((res.ring->center - ocam).norm(), 12.0);
  EXPECT_NEAR(res.ring->radius_inner, 235.0, 8.0);
  EXPECT_NEAR(res.ring->radius_outer, 600.0, 10.0);
  const auto& d = res.detections.front();
  EXPECT_LT((d.inner.circle.center - d.outer.circle.center).norm(), 3.0);
  // The floor is around the camera's reflection, windows and walls outside: outer = up.
  EXPECT_EQ(res.calibration.omni.outer_edge, OuterEdge::kTop);
  EXPECT_TRUE(res.outer_edge && res.outer_edge->decisive);
}

}  // namespace
}  // namespace omnipose::calibrate
