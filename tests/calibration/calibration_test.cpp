#include "omnipose/calibration.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <numbers>
#include <string>
#include <utility>

using ::testing::HasSubstr;
using ::testing::Not;

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

/// The problems Calibration::parse lists for kValid followed by `sections`, from a file
/// named cal.yaml (empty when it parses).
std::string problemsOf(const std::string& sections) {
  try {
    Calibration::parse(std::string(kValid) + sections, "cal.yaml");
  } catch (const CalibrationError& e) {
    return e.what();
  }
  return {};
}

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
    EXPECT_THAT(what, HasSubstr("cal.yaml: omni.image_height"));
    EXPECT_THAT(what, HasSubstr("omni.center"));
    EXPECT_THAT(what, HasSubstr("omni.radius_outer: missing"));
    EXPECT_THAT(what, HasSubstr("omni.azimuth_direction"));
    EXPECT_THAT(what, HasSubstr("omni.colour: unknown key"));
    EXPECT_THAT(what, HasSubstr("extra: unknown section"));
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
  EXPECT_THAT(all, HasSubstr("omni.radius_outer"));
  EXPECT_THAT(all, HasSubstr("omni.center"));
  EXPECT_THAT(all, HasSubstr("panorama.height"));
}

TEST(Calibration, MissingFileIsNamed) {
  try {
    Calibration::load("/nonexistent/calibration.yaml");
    FAIL();
  } catch (const CalibrationError& e) {
    EXPECT_THAT(e.what(), HasSubstr("/nonexistent/calibration.yaml"));
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

TEST(CalibrationSensor, ReadoutTimeIsReadValidatedAndSaved) {
  EXPECT_EQ(Calibration::parse(kValid).sensor.readout_s, 0.0) << "no section: global shutter";
  const Calibration c =
      Calibration::parse(std::string(kValid) + "sensor:\n  readout_s: -0.0267\n");
  EXPECT_DOUBLE_EQ(c.sensor.readout_s, -0.0267);
  EXPECT_THAT(c.toYaml(), HasSubstr("sensor:\n  readout_s: -0.0267"));
  EXPECT_THAT(Calibration::parse(kValid).toYaml(), Not(HasSubstr("sensor")))
      << "a global shutter writes no section: files stay as they were";

  for (const char* bad : {"sensor:\n  readout_s: 0.15\n", "sensor:\n  readout_s: -0.2\n",
                          "sensor:\n  readout_s: .nan\n", "sensor:\n  readout_s: fast\n"}) {
    const std::string what = problemsOf(bad);
    EXPECT_THAT(what, HasSubstr("cal.yaml: sensor.readout_s")) << bad << what;
  }
  EXPECT_THAT(problemsOf("sensor:\n  shutter_s: 0.01\n"),
              HasSubstr("sensor.shutter_s: unknown key"));
  EXPECT_EQ(problemsOf("sensor:\n  readout_s: 0.1\n"), "") << "the longest readout is allowed";
}

TEST(CalibrationSensor, ExposureTimeIsReadValidatedAndSaved) {
  EXPECT_EQ(Calibration::parse(kValid).sensor.exposure_s, 0.0) << "not known";
  const Calibration c = Calibration::parse(std::string(kValid) + "sensor:\n  exposure_s: 0.008\n");
  EXPECT_DOUBLE_EQ(c.sensor.exposure_s, 0.008);
  EXPECT_EQ(c.sensor.readout_s, 0.0);
  EXPECT_THAT(c.toYaml(), HasSubstr("sensor:\n  exposure_s: 0.008"));
  EXPECT_DOUBLE_EQ(Calibration::parse(c.toYaml()).sensor.exposure_s, 0.008);
  const Calibration both = Calibration::parse(
      std::string(kValid) + "sensor:\n  readout_s: 0.0267\n  exposure_s: 0.01\n");
  EXPECT_THAT(both.toYaml(), HasSubstr("sensor:\n  readout_s: 0.0267\n  exposure_s: 0.01\n"));
  for (const char* bad : {"sensor:\n  exposure_s: -0.001\n", "sensor:\n  exposure_s: 0.2\n",
                          "sensor:\n  exposure_s: .inf\n", "sensor:\n  exposure_s: long\n"}) {
    const std::string what = problemsOf(bad);
    EXPECT_THAT(what, HasSubstr("cal.yaml: sensor.exposure_s")) << bad << what;
  }
  // Both bad: both named.
  const std::string two = problemsOf("sensor:\n  readout_s: 0.5\n  exposure_s: -1\n");
  EXPECT_THAT(two, HasSubstr("sensor.readout_s"));
  EXPECT_THAT(two, HasSubstr("sensor.exposure_s"));
}

TEST(CalibrationSensor, WhereTheCameraStampsAFrameIsReadValidatedAndSaved) {
  EXPECT_EQ(Calibration::parse(kValid).sensor.stamped_at, StampedAt::kExposureMiddle);
  EXPECT_THAT(Calibration::parse(kValid).toYaml(), Not(HasSubstr("timestamp:")));
  for (const StampedAt at : {StampedAt::kExposureStart, StampedAt::kExposureEnd}) {
    const Calibration c = Calibration::parse(std::string(kValid) + "sensor:\n  timestamp: " +
                                             toString(at) + "\n");
    EXPECT_EQ(c.sensor.stamped_at, at);
    EXPECT_EQ(Calibration::parse(c.toYaml()).sensor.stamped_at, at) << c.toYaml();
  }
  SensorTiming t;
  EXPECT_EQ(t.captureTimeOffset(0.01), 0.0);
  t.stamped_at = StampedAt::kExposureStart;
  EXPECT_DOUBLE_EQ(t.captureTimeOffset(0.01), 0.005);
  t.stamped_at = StampedAt::kExposureEnd;
  EXPECT_DOUBLE_EQ(t.captureTimeOffset(0.01), -0.005);
  const std::string what = problemsOf("sensor:\n  timestamp: readout\n");
  EXPECT_THAT(what, HasSubstr("cal.yaml: sensor.timestamp: 'readout' is not"));
  EXPECT_THAT(what, HasSubstr("exposure_end"));
}

TEST(CalibrationImu, TheGyrosMountingAndClockAreReadValidatedAndSaved) {
  EXPECT_FALSE(Calibration::parse(kValid).imu.has_value()) << "no section: no gyro";
  EXPECT_THAT(Calibration::parse(kValid).toYaml(), Not(HasSubstr("imu:")));
  // A hand-written quaternion of 4 digits is normalised; the optional keys default.
  const Calibration c = Calibration::parse(
      std::string(kValid) + "imu:\n  rotation: [0.7071, 0, 0, 0.7071]\n  time_offset_s: -0.0042\n"
                            "  gyro_noise_density: 8.7e-5\n");
  ASSERT_TRUE(c.imu.has_value());
  EXPECT_NEAR(c.imu->rotation.norm(), 1.0, 1e-15);
  EXPECT_NEAR(c.imu->rotation.w(), std::sqrt(0.5), 1e-15);
  EXPECT_NEAR(c.imu->rotation.z(), std::sqrt(0.5), 1e-15);
  EXPECT_DOUBLE_EQ(c.imu->time_offset_s, -0.0042);
  EXPECT_DOUBLE_EQ(c.imu->gyro_noise_density.value_or(0.0), 8.7e-5);
  const Calibration saved = Calibration::parse(c.toYaml());
  ASSERT_TRUE(saved.imu.has_value());
  EXPECT_TRUE(saved.imu->rotation.isApprox(c.imu->rotation, 1e-15));
  EXPECT_EQ(saved.imu->time_offset_s, c.imu->time_offset_s);
  EXPECT_EQ(saved.imu->gyro_noise_density, c.imu->gyro_noise_density);
  const Calibration bare = Calibration::parse(std::string(kValid) + "imu:\n  rotation: [1, 0, 0, 0]\n");
  ASSERT_TRUE(bare.imu.has_value());
  EXPECT_EQ(bare.imu->time_offset_s, 0.0);
  EXPECT_FALSE(bare.imu->gyro_noise_density.has_value());
  EXPECT_FALSE(Calibration::parse(bare.toYaml()).imu->gyro_noise_density.has_value());

  const std::pair<const char*, const char*> cases[] = {
      {"imu:\n  rotation: [1, 0, 0.1, 0]\n", "cal.yaml: imu.rotation: [w, x, y, z] must be a unit quaternion"},
      {"imu:\n  rotation: [1, 0, 0]\n", "cal.yaml: imu.rotation"},
      {"imu:\n  rotation: [1, 0, 0, .nan]\n", "cal.yaml: imu.rotation"},
      {"imu:\n  time_offset_s: 0.0\n", "cal.yaml: imu.rotation: missing"},
      {"imu:\n  rotation: [1, 0, 0, 0]\n  time_offset_s: 1.5\n", "cal.yaml: imu.time_offset_s"},
      {"imu:\n  rotation: [1, 0, 0, 0]\n  gyro_noise_density: 0\n", "cal.yaml: imu.gyro_noise_density"},
      {"imu:\n  rotation: [1, 0, 0, 0]\n  bias: [0, 0, 0]\n", "imu.bias: unknown key"},
      {"imu: [1, 0, 0, 0]\n", "cal.yaml: imu"},
  };
  for (const auto& [bad, needle] : cases) EXPECT_THAT(problemsOf(bad), HasSubstr(needle)) << bad;
  // Every problem of the section at once.
  const std::string all =
      problemsOf("imu:\n  rotation: [2, 0, 0, 0]\n  time_offset_s: -3\n  gyro_noise_density: -1\n");
  for (const char* field : {"imu.rotation", "imu.time_offset_s", "imu.gyro_noise_density"})
    EXPECT_THAT(all, HasSubstr(field)) << all;
}

TEST(CalibrationSensor, EveryPanoramaPixelIsCapturedWhenItsOmniRowIsRead) {
  Calibration c = Calibration::parse(kValid);
  EXPECT_EQ(c.captureTime(100.0, 50.0), 0.0) << "global shutter";
  for (const double readout : {0.0267, -0.0267}) {
    c.sensor.readout_s = readout;
    for (const auto& [u, v] : {std::pair{0.0, 0.0}, {275.0, 54.5}, {550.0, 109.0}, {812.3, 20.7}}) {
      const double y = c.omniPixel(u, v).y();
      const double expected = readout > 0 ? readout * y / 720.0 : -readout * (719.0 - y) / 720.0;
      EXPECT_NEAR(c.captureTime(u, v), expected, 1e-15) << u << " " << v;
      EXPECT_GE(c.captureTime(u, v), 0.0);
      EXPECT_LE(c.captureTime(u, v), std::abs(readout));
    }
  }
  EXPECT_EQ(rowTime(0.0, 720, 0.0267), 0.0);
  EXPECT_DOUBLE_EQ(rowTime(360.0, 720, 0.0267), 0.0267 / 2);
  EXPECT_EQ(rowTime(719.0, 720, -0.0267), 0.0) << "reversed: the last row is read first";
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

namespace omnipose {
namespace {

/// The ConfigError of parsing `text` as calibration.yaml ("" and no problems when valid).
std::pair<std::string, std::vector<std::string>> calibrationError(const std::string& text) {
  try {
    Calibration::parse(text, "cal.yaml");
  } catch (const ConfigError& e) {
    return {e.what(), e.problems()};
  }
  return {};
}

int lineCount(const std::string& text) {
  return static_cast<int>(std::count(text.begin(), text.end(), '\n')) + 1;
}

TEST(CalibrationYaml, DuplicateKeysAtEveryLevelNameTheKeyAndBothLines) {
  const std::string text = std::string(kValid) + "omni:\n  image_width: 720\n";  // omni again
  auto [what, problems] = calibrationError(text);
  EXPECT_THAT(what, HasSubstr("cal.yaml: omni: given twice, lines 1 and 15"));
  std::string nested = kValid;
  nested.insert(nested.find("panorama:"), "  radius_inner: -5\n");  // line 10, first at 5
  std::tie(what, problems) = calibrationError(nested);
  EXPECT_THAT(what, HasSubstr("cal.yaml: omni.radius_inner: given twice, lines 5 and 10"));
  std::tie(what, problems) =
      calibrationError("omni: {image_width: 720, image_width: abc}\npanorama: {width: 1, width: [1, 2]}\n");
  EXPECT_THAT(what, HasSubstr("omni.image_width: given twice, lines 1 and 1"));
  EXPECT_THAT(what, HasSubstr("panorama.width: given twice, lines 2 and 2"));
}

TEST(CalibrationYaml, LongStringsAreProblemsAndEchoedShort) {
  std::string text = kValid;
  text.insert(text.find("panorama:"), "  mask: " + std::string(5'000'000, 'm') + "\n");
  const auto [what, problems] = calibrationError(text);
  EXPECT_LT(what.size(), 1024u) << what.substr(0, 2000);
  EXPECT_THAT(what,
              HasSubstr("omni.mask: '" + std::string(60, 'm') +
                        "... (5000000 bytes)' is longer than 4096 bytes"))
      << what.substr(0, 2000);
  // At the bound: accepted as a string (the mask file itself does not exist).
  std::string at_bound = kValid;
  at_bound.insert(at_bound.find("panorama:"), "  mask: " + std::string(4096, 'm') + "\n");
  EXPECT_THAT(calibrationError(at_bound).first, Not(HasSubstr("longer than")));
}

TEST(CalibrationYaml, ControlCharactersAreEscapedSoNothingCutsTheMessage) {
  std::string text = kValid;
  text.replace(text.find("azimuth_direction: cw"), 21, "azimuth_direction: \"c\\x01w\"");
  text.insert(text.find("panorama:"), "  \"col\\0our\\t\": 1\n");
  const auto [what, problems] = calibrationError(text);
  EXPECT_EQ(std::string(what.c_str()), what) << "a NUL in what()";
  EXPECT_THAT(what, HasSubstr("omni.col\\0our\\t: unknown key"));
  EXPECT_THAT(what, HasSubstr("omni.azimuth_direction: 'c\\x01w' is not cw or ccw"));
  for (const auto& p : problems) EXPECT_EQ(std::string(p.c_str()), p);
}

TEST(CalibrationYaml, AtMostTwentyProblemsAreListedThenHowManyMore) {
  std::string text = kValid;
  for (int i = 0; i < 30; ++i) text += "extra" + std::to_string(i) + ": 1\n";
  const auto [what, problems] = calibrationError(text);
  EXPECT_EQ(problems.size(), 30u);
  EXPECT_EQ(lineCount(what), 22) << what;  // heading, 20 problems, "and 10 more"
  EXPECT_THAT(what, HasSubstr("\n  and 10 more"));
  EXPECT_THAT(what, HasSubstr("extra19: unknown section"));
  EXPECT_THAT(what, Not(HasSubstr("extra20: unknown section")));
}

}  // namespace
}  // namespace omnipose
