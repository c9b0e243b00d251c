#include "omnipose/calibration.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <numbers>

namespace omnipose {
namespace {

const char* kValid = R"(omni:
  image_width: 720
  image_height: 720
  center: [359.5, 359.5]
  radius_inner: 120.0
  radius_outer: 300.0
  azimuth_zero_deg: 0.0
  azimuth_direction: cw
  outer_edge: top
panorama:
  width: 1100
  height: 110
  horizon_row: 54.5
  forward_column: 0.0
)";

TEST(Calibration, ParsesTheDesignExample) {
  const Calibration c = Calibration::parse(kValid);
  EXPECT_EQ(c.omni.image_width, 720);
  EXPECT_DOUBLE_EQ(c.omni.center_x, 359.5);
  EXPECT_DOUBLE_EQ(c.omni.radius_outer, 300.0);
  EXPECT_EQ(c.omni.azimuth_direction, AzimuthDirection::kCw);
  EXPECT_EQ(c.omni.outer_edge, OuterEdge::kTop);
  EXPECT_EQ(c.panorama.width, 1100);
  EXPECT_DOUBLE_EQ(c.panorama.horizon_row, 54.5);
  EXPECT_TRUE(c.validate().empty());
}

TEST(Calibration, ReportsEveryBadFieldAtOnce) {
  const std::string text = R"(omni:
  image_width: 720
  image_height: abc
  center: [359.5]
  radius_inner: 120.0
  azimuth_direction: sideways
  colour: red
panorama:
  width: 1100
  height: 110
extra: 1
)";
  try {
    Calibration::parse(text, "cal.yaml");
    FAIL() << "expected CalibrationError";
  } catch (const CalibrationError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("cal.yaml: omni.image_height"), std::string::npos) << what;
    EXPECT_NE(what.find("omni.center"), std::string::npos) << what;
    EXPECT_NE(what.find("omni.radius_outer: missing"), std::string::npos) << what;
    EXPECT_NE(what.find("omni.azimuth_direction"), std::string::npos) << what;
    EXPECT_NE(what.find("omni.colour: unknown key"), std::string::npos) << what;
    EXPECT_NE(what.find("extra: unknown section"), std::string::npos) << what;
    EXPECT_EQ(e.problems().size(), 6u) << what;
  }
}

TEST(Calibration, RangeChecksNameTheField) {
  Calibration c = Calibration::parse(kValid);
  c.omni.radius_inner = 310;   // inner > outer
  c.omni.center_x = 800;       // outside the image
  c.panorama.height = 0;
  const auto problems = c.validate();
  ASSERT_GE(problems.size(), 3u);
  std::string all;
  for (const auto& p : problems) all += p + "\n";
  EXPECT_NE(all.find("omni.radius_outer"), std::string::npos) << all;
  EXPECT_NE(all.find("omni.center"), std::string::npos) << all;
  EXPECT_NE(all.find("panorama.height"), std::string::npos) << all;
}

TEST(Calibration, MissingFileIsNamed) {
  try {
    Calibration::load("/nonexistent/calibration.yaml");
    FAIL();
  } catch (const CalibrationError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/calibration.yaml"), std::string::npos);
  }
}

TEST(Calibration, SaveLoadRoundTrip) {
  Calibration c = Calibration::parse(kValid);
  c.omni.center_x = 351.25;
  c.omni.azimuth_direction = AzimuthDirection::kCcw;
  c.omni.outer_edge = OuterEdge::kBottom;
  c.omni.azimuth_zero_deg = -37.5;
  const auto path = std::filesystem::temp_directory_path() / "omnipose_calibration_test.yaml";
  c.save(path);
  const Calibration d = Calibration::load(path);
  EXPECT_DOUBLE_EQ(d.omni.center_x, 351.25);
  EXPECT_EQ(d.omni.azimuth_direction, AzimuthDirection::kCcw);
  EXPECT_EQ(d.omni.outer_edge, OuterEdge::kBottom);
  EXPECT_DOUBLE_EQ(d.omni.azimuth_zero_deg, -37.5);
  std::filesystem::remove(path);
}

// DESIGN.md section 6: a = azimuth_zero + theta (cw) / - theta (ccw); outer ring -> top row.
TEST(Calibration, OmniPixelFollowsTheDesignConventions) {
  Calibration c = Calibration::parse(kValid);
  const double W = c.panorama.width, H = c.panorama.height;
  // u = W/4 is theta = +90 deg (the robot's left). cw: a = +90 deg, i.e. below the centre.
  Eigen::Vector2d p = c.omniPixel(W / 4, -0.5);  // top edge of row 0 = outer radius
  EXPECT_NEAR(p.x(), 359.5, 1e-9);
  EXPECT_NEAR(p.y(), 359.5 + 300.0, 1e-9);
  c.omni.azimuth_direction = AzimuthDirection::kCcw;
  p = c.omniPixel(W / 4, -0.5);
  EXPECT_NEAR(p.y(), 359.5 - 300.0, 1e-9);
  c.omni.outer_edge = OuterEdge::kBottom;
  p = c.omniPixel(0, H - 0.5);  // bottom edge = outer radius, theta = 0: a = 0, right
  EXPECT_NEAR(p.x(), 359.5 + 300.0, 1e-9);
  EXPECT_NEAR(p.y(), 359.5, 1e-9);
}

TEST(Calibration, PanoramaPixelInvertsOmniPixelForAllLensVariants) {
  for (auto dir : {AzimuthDirection::kCw, AzimuthDirection::kCcw}) {
    for (auto edge : {OuterEdge::kTop, OuterEdge::kBottom}) {
      Calibration c = Calibration::parse(kValid);
      c.omni.azimuth_direction = dir;
      c.omni.outer_edge = edge;
      c.omni.azimuth_zero_deg = 33.0;
      c.panorama.forward_column = 120.0;
      for (double u : {0.0, 17.3, 550.0, 1099.5}) {
        for (double v : {0.0, 54.5, 109.0}) {
          const Eigen::Vector2d p = c.omniPixel(u, v);
          const Eigen::Vector2d q = c.panoramaPixel(p.x(), p.y());
          EXPECT_NEAR(std::remainder(q.x() - u, 1100.0), 0.0, 1e-9);
          EXPECT_NEAR(q.y(), v, 1e-9);
        }
      }
    }
  }
}

TEST(PanoramaGeometry, BearingConventions) {
  PanoramaGeometry g;
  g.forward_column = 100;
  const Eigen::Vector3d fwd = g.bearing(100, g.horizon_row);
  EXPECT_NEAR(fwd.x(), 1.0, 1e-12);
  const Eigen::Vector3d left = g.bearing(100 + g.width / 4.0, g.horizon_row);
  EXPECT_NEAR(left.y(), 1.0, 1e-12);  // counter-clockwise seen from above: +y is left
  const Eigen::Vector3d up = g.bearing(100, g.horizon_row - 10);
  EXPECT_GT(up.z(), 0.0);  // rows above the horizon look up
  EXPECT_NEAR(up.z() / up.x(), 10 * g.gamma(), 1e-12);
  EXPECT_NEAR(g.column(-g.gamma()), 99.0, 1e-9);
  EXPECT_NEAR(g.row(g.cylinderHeight(3.25)), 3.25, 1e-12);
}

}  // namespace
}  // namespace omnipose
