// Lens models: OCamCalib and Mei in both directions, their YAML keys, and the
// start-up errors for bad lens files.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <sstream>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "omnipose/calibration.hpp"
#include "omnipose/lens_model.hpp"
#include "test_files.hpp"

using ::testing::HasSubstr;
using ::testing::Not;

namespace omnipose {
namespace {

namespace fs = std::filesystem;
constexpr double kPi = std::numbers::pi;

const fs::path kData = fs::path(OMNIPOSE_SOURCE_DIR) / "tests/data/catadioptric";
const fs::path kOffice = kData / "mirror_office_ocamcalib.txt";
const fs::path kSteep = kData / "steep_mirror_800_ocamcalib.txt";

using testing::TempDir;

std::string ocamYaml(const std::string& file, const std::string& extra = "") {
  return "omni:\n  model: ocamcalib\n  ocamcalib_file: " + file +
         "\n  azimuth_direction: ccw\n" + extra +
         "panorama: {width: 1100, height: 110, horizon_row: 54.5}\n";
}

/// Every problem of the CalibrationError that `read` throws, or "" when it succeeds.
template <typename Read>
std::string errorOf(const Read& read) {
  try {
    read();
  } catch (const CalibrationError& e) {
    return e.what();
  }
  return "";
}

/// Every problem of a CalibrationError, or "" when parsing succeeded.
std::string parseError(const std::string& yaml, const fs::path& base) {
  return errorOf([&] { Calibration::parse(yaml, "cal.yaml", base); });
}

// ---------------------------------------------------------------------------------------
// OCamCalib
// ---------------------------------------------------------------------------------------

TEST(OcamCalib, ReadsTheRealFileWithItsCrop) {
  const OcamCalibModel m = OcamCalibModel::load(kOffice);
  ASSERT_EQ(m.ss.size(), 5u);
  EXPECT_DOUBLE_EQ(m.ss[0], -266.588);
  EXPECT_EQ(m.invpol.size(), 12u);
  // Calibrated on a 1300-wide crop with 300 px cut on the left: frame column = +300.
  EXPECT_EQ(m.width, 1920);
  EXPECT_EQ(m.height, 1080);
  EXPECT_NEAR(m.yc, 674.318875 + 300.0, 1e-9);
  EXPECT_NEAR(m.xc, 545.872616, 1e-9);
  ASSERT_TRUE(m.roi_max_radius && m.roi_min_radius);
  EXPECT_DOUBLE_EQ(*m.roi_max_radius, 600.0);
  EXPECT_DOUBLE_EQ(*m.roi_min_radius, 235.0);
  EXPECT_EQ(m.crop_left, 300);
  EXPECT_EQ(m.crop_right, 320);
}

// cam2world as OCamCalib writes it, evaluated by hand on one pixel.
TEST(OcamCalib, Cam2WorldMatchesOcamCalibsDefinition) {
  const OcamCalibModel m = OcamCalibModel::load(kOffice);
  const double row = 700.0, col = 1200.0;
  const double invdet = 1.0 / (m.c - m.d * m.e);
  const double xp = invdet * ((row - m.xc) - m.d * (col - m.yc));
  const double yp = invdet * (-m.e * (row - m.xc) + m.c * (col - m.yc));
  const double r = std::hypot(xp, yp);
  const double z = m.ss[0] + m.ss[2] * r * r + m.ss[3] * r * r * r + m.ss[4] * r * r * r * r;
  const LensDirection d = m.direction({col, row});
  EXPECT_NEAR(d.radius, r, 1e-9);
  EXPECT_NEAR(d.elevation, std::atan2(z, r), 1e-12);
  EXPECT_NEAR(d.image_angle, std::atan2(xp, yp), 1e-12);
  // world2cam from OCamCalib's invpol lands within its fit error of the same pixel, and the
  // refined inverse exactly on it.
  const auto rho = m.radius(d.elevation);
  ASSERT_TRUE(rho);
  const Eigen::Vector2d back = m.pixel(d.image_angle, *rho);
  EXPECT_NEAR(back.x(), col, 1e-6);
  EXPECT_NEAR(back.y(), row, 1e-6);
  EXPECT_LT(m.invpolMaxErrorPx(235, 600), 1.0) << "invpol far from ss";
}

/// Pixel -> bearing -> pixel over the whole used ring, through the Calibration.
void expectRoundTrip(const Calibration& c, double tolerance_px) {
  double worst = 0.0;
  int n = 0;
  for (double r = c.omni.radius_inner; r <= c.omni.radius_outer; r += (c.omni.radius_outer - c.omni.radius_inner) / 23) {
    for (int k = 0; k < 72; ++k) {
      const double a = 2 * kPi * k / 72 + 0.013;
      const double x = c.omni.center_x + r * std::cos(a), y = c.omni.center_y + r * std::sin(a);
      const auto b = c.bearingOfPixel(x, y);
      ASSERT_TRUE(b) << "no bearing at " << x << "," << y;
      EXPECT_NEAR(b->norm(), 1.0, 1e-12);
      const auto p = c.pixelOfBearing(*b);
      ASSERT_TRUE(p) << "no pixel for the bearing of " << x << "," << y;
      worst = std::max(worst, (*p - Eigen::Vector2d(x, y)).norm());
      ++n;
    }
  }
  EXPECT_LT(worst, tolerance_px) << "worst of " << n << " pixels";
}

TEST(OcamCalib, PixelBearingPixelRoundTripOverTheRing) {
  for (const auto& file : {kOffice, kSteep}) {
    const Calibration c = Calibration::parse(ocamYaml(file.string()), "cal.yaml");
    SCOPED_TRACE(file.string());
    expectRoundTrip(c, 0.01);
    // And panorama pixel -> omni pixel -> panorama pixel.
    for (double u : {0.0, 313.7, 1099.0}) {
      for (double v : {0.0, 54.5, 109.0}) {
        const Eigen::Vector2d p = c.omniPixel(u, v);
        const Eigen::Vector2d q = c.panoramaPixel(p.x(), p.y());
        EXPECT_NEAR(std::remainder(q.x() - u, 1100.0), 0.0, 1e-6);
        EXPECT_NEAR(q.y(), v, 1e-6);
      }
    }
  }
}

// +z of OCamCalib's frame is up: the outer ring of a mirror looks higher than the inner.
TEST(OcamCalib, ElevationGrowsOutwardsAndRowsFollowIt) {
  const Calibration c = Calibration::parse(ocamYaml(kOffice.string()), "cal.yaml");
  const auto [e_in, e_out] = c.ringElevations();
  EXPECT_NEAR(e_in * 180 / kPi, -40.5, 0.3);
  EXPECT_NEAR(e_out * 180 / kPi, 27.1, 0.3);
  // Top row of the panorama (up) is further out in the image than the bottom row.
  const Eigen::Vector2d top = c.omniPixel(100, 0), bottom = c.omniPixel(100, 109);
  EXPECT_GT(c.ringRadius(top.x(), top.y()), c.ringRadius(bottom.x(), bottom.y()));
  // The horizon row looks at elevation 0.
  const auto b = c.bearingOfPixel(c.omniPixel(100, 54.5).x(), c.omniPixel(100, 54.5).y());
  ASSERT_TRUE(b);
  EXPECT_NEAR(b->z(), 0.0, 1e-9);
}

// Azimuth keys relate the image angle to the robot's +x axis as for the linear model.
TEST(OcamCalib, AzimuthKeysTurnTheImageAngle) {
  Calibration c = Calibration::parse(ocamYaml(kSteep.string(), "  azimuth_zero_deg: 30\n"), "cal.yaml");
  for (auto dir : {AzimuthDirection::kCw, AzimuthDirection::kCcw}) {
    c.omni.azimuth_direction = dir;
    // Robot azimuth +90 deg (left) at the horizon.
    const auto p = c.pixelOfBearing({0, 1, 0});
    ASSERT_TRUE(p);
    const LensDirection d = c.omni.ocamcalib->direction(*p);
    const double expected = (30.0 + (dir == AzimuthDirection::kCw ? 90.0 : -90.0)) * kPi / 180;
    EXPECT_NEAR(std::remainder(d.image_angle - expected, 2 * kPi), 0.0, 1e-9);
  }
}

TEST(OcamCalib, RingDefaultsToTheRoiAndImageSizeToTheFile) {
  const Calibration c = Calibration::parse(ocamYaml(kOffice.string()), "cal.yaml");
  EXPECT_EQ(c.omni.image_width, 1920);
  EXPECT_EQ(c.omni.image_height, 1080);
  EXPECT_DOUBLE_EQ(c.omni.radius_inner, 235.0);
  EXPECT_DOUBLE_EQ(c.omni.radius_outer, 600.0);
  EXPECT_NEAR(c.omni.center_x, 974.318875, 1e-9);
  const Calibration d = Calibration::parse(
      ocamYaml(kOffice.string(), "  radius_inner: 260\n  radius_outer: 580\n"), "cal.yaml");
  EXPECT_DOUBLE_EQ(d.omni.radius_inner, 260.0);
  EXPECT_DOUBLE_EQ(d.omni.radius_outer, 580.0);
}

TEST(OcamCalib, FileIsRelativeToTheYamlAndSaveWritesItBeside) {
  TempDir dir;
  fs::copy_file(kSteep, dir.path() / "calib_results.txt");
  dir.write("calibration.yaml", ocamYaml("calib_results.txt"));
  const Calibration c = Calibration::load(dir.path() / "calibration.yaml");
  ASSERT_TRUE(c.omni.ocamcalib);
  fs::create_directories(dir.path() / "copy");
  c.save(dir.path() / "copy/calibration.yaml");
  EXPECT_TRUE(fs::exists(dir.path() / "copy/calib_results.txt"));
  const Calibration d = Calibration::load(dir.path() / "copy/calibration.yaml");
  EXPECT_EQ(d.omni.model, LensModelKind::kOcamCalib);
  EXPECT_EQ(d.omni.ocamcalib->ss, c.omni.ocamcalib->ss);
  EXPECT_EQ(d.omniPixel(123.4, 56.7), c.omniPixel(123.4, 56.7));
}

TEST(OcamCalib, BadFilesNameTheFileAndTheLine) {
  TempDir dir;
  const std::string good = omnipose::testing::readText(kOffice);
  // Truncated after the centre line.
  const std::string truncated = good.substr(0, good.find("#affine"));
  dir.write("truncated.txt", truncated);
  std::string what = parseError(ocamYaml("truncated.txt"), dir.path());
  EXPECT_THAT(what, HasSubstr("omni.ocamcalib_file"));
  EXPECT_THAT(what, HasSubstr("truncated.txt"));
  EXPECT_THAT(what, HasSubstr("affine"));
  EXPECT_THAT(what, HasSubstr("end of the file"));

  // A coefficient that is not a number, on line 3.
  std::string bad = good;
  bad.replace(bad.find("1.220001e-03"), 12, "1.22x01e-03");
  dir.write("garbled.txt", bad);
  what = parseError(ocamYaml("garbled.txt"), dir.path());
  EXPECT_THAT(what, HasSubstr("garbled.txt: line 3"));
  EXPECT_THAT(what, HasSubstr("'1.22x01e-03' is not a number"));

  // The count disagrees with the coefficients.
  bad = good;
  bad.replace(bad.find("\n5 -2.66"), 3, "\n6 ");
  dir.write("count.txt", bad);
  what = parseError(ocamYaml("count.txt"), dir.path());
  EXPECT_THAT(what, HasSubstr("line 3: ss: the count says 6 coefficients, the line has 5"));

  // Missing file.
  what = parseError(ocamYaml("absent.txt"), dir.path());
  EXPECT_THAT(what, HasSubstr("absent.txt: no such file"));
}

TEST(OcamCalib, NonMonotonicPolynomialOverTheRingIsRefused) {
  TempDir dir;
  std::string text = omnipose::testing::readText(kSteep);
  // A large rho^2 term with a negative rho^3 term: the elevation turns inside the ring.
  const auto at = text.find("\n5 ") + 1;
  const auto end = text.find('\n', at);
  text.replace(at, end - at, "5 -1.776981460e+02 0 6.0e-03 -1.6e-05 0");
  dir.write("turning.txt", text);
  const std::string what = parseError(ocamYaml("turning.txt"), dir.path());
  EXPECT_THAT(what,
              HasSubstr("turning.txt: line 3: the direct polynomial is not monotonic over the "
                        "ring"));
}

TEST(OcamCalib, PanoramaRowsOutsideTheRingAreNamed) {
  // 400 rows of 0.33 deg: +-65 deg, far beyond the ring's -45..+28.7 deg.
  const std::string yaml = "omni:\n  model: ocamcalib\n  ocamcalib_file: " + kSteep.string() +
                           "\npanorama: {width: 1100, height: 400}\n";
  const std::string what = parseError(yaml, {});
  EXPECT_THAT(what, HasSubstr("panorama: rows 0.."));
  EXPECT_THAT(what, HasSubstr("lie outside the lens ring (elevations -45."));
}

TEST(OcamCalib, KeysOfOtherModelsAreRefused) {
  const std::string what =
      parseError(ocamYaml(kSteep.string(), "  center: [1, 2]\n  xi: 0.8\n  outer_edge: top\n"), {});
  EXPECT_THAT(what, HasSubstr("omni.center: not used with model ocamcalib"));
  EXPECT_THAT(what, HasSubstr("omni.xi: not used with model ocamcalib"));
  EXPECT_THAT(what, HasSubstr("omni.outer_edge: not used with model ocamcalib"));
}

// ---------------------------------------------------------------------------------------
// Mei (cv::omnidir)
// ---------------------------------------------------------------------------------------

/// The calibration.yaml of an 800 x 800 Mei lens whose parameters are in omnidir file `file`.
std::string meiWithFile(const std::string& file) {
  return "omni:\n  model: mei\n  omnidir_file: " + file +
         "\n  image_width: 800\n  image_height: 800\n  radius_inner: 90\n  radius_outer: 330\n"
         "panorama: {width: 1100, height: 110}\n";
}

const char* kMeiYaml = R"(omni:
  model: mei
  image_width: 800
  image_height: 800
  xi: 0.92
  K: [[205.0, 0.3, 401.5], [0, 204.2, 398.0], [0, 0, 1]]
  D: [-0.04, 0.006, 0.0004, -0.0003]
  radius_inner: 90
  radius_outer: 330
  azimuth_direction: ccw
panorama: {width: 1100, height: 110}
)";

TEST(Mei, ProjectUnprojectRoundTrip) {
  const Calibration c = Calibration::parse(kMeiYaml, "cal.yaml");
  ASSERT_TRUE(c.omni.mei);
  EXPECT_DOUBLE_EQ(c.omni.center_x, 401.5);
  expectRoundTrip(c, 0.01);
}

// The unified model by hand: a horizontal bearing lands at x = xs / xi (no distortion).
TEST(Mei, HorizonFollowsTheUnifiedModel) {
  MeiModel m;
  m.xi = 0.8;
  m.fx = m.fy = 200;
  m.cx = 400;
  m.cy = 300;
  const auto p = m.pixel(0.0, 0.0);
  ASSERT_TRUE(p);
  EXPECT_NEAR(p->x(), 400 + 200 * (1.0 / 0.8), 1e-9);
  EXPECT_NEAR(p->y(), 300, 1e-9);
  // Up is -z: a bearing above the horizon lands further out (the mirror's outer ring).
  const auto up = m.pixel(0.0, 0.2);
  ASSERT_TRUE(up);
  EXPECT_GT(up->x(), p->x());
  // Image centre looks straight down.
  const auto d = m.direction({400, 300});
  ASSERT_TRUE(d);
  EXPECT_NEAR(d->elevation, -kPi / 2, 1e-9);
}

TEST(Mei, ReadsAnOmnidirFileStorage) {
  TempDir dir;
  {
    cv::FileStorage fs((dir.path() / "omnidir.yml").string(), cv::FileStorage::WRITE);
    fs << "K" << (cv::Mat_<double>(3, 3) << 205.0, 0.3, 401.5, 0, 204.2, 398.0, 0, 0, 1);
    fs << "D" << (cv::Mat_<double>(1, 4) << -0.04, 0.006, 0.0004, -0.0003);
    fs << "xi" << (cv::Mat_<double>(1, 1) << 0.92);
  }
  dir.write("cal.yaml", meiWithFile("omnidir.yml"));
  const Calibration c = Calibration::load(dir.path() / "cal.yaml");
  ASSERT_TRUE(c.omni.mei);
  EXPECT_DOUBLE_EQ(c.omni.mei->xi, 0.92);
  EXPECT_DOUBLE_EQ(c.omni.mei->fy, 204.2);
  EXPECT_DOUBLE_EQ(c.omni.mei->p2, -0.0003);
  // Missing key named.
  {
    cv::FileStorage fs((dir.path() / "bad.yml").string(), cv::FileStorage::WRITE);
    fs << "K" << (cv::Mat_<double>(3, 3) << 205.0, 0, 401.5, 0, 204.2, 398.0, 0, 0, 1);
  }
  dir.write("bad.yaml", meiWithFile("bad.yml"));
  const std::string what = errorOf([&] { Calibration::load(dir.path() / "bad.yaml"); });
  ASSERT_FALSE(what.empty()) << "expected an error";
  EXPECT_THAT(what, HasSubstr("bad.yml: D: missing"));
  EXPECT_THAT(what, HasSubstr("bad.yml: xi: missing"));
}

TEST(Mei, AMatrixDeclaringAHugeShapeIsRefusedBeforeItIsAllocated) {
  // Found by fuzz_lens_mask: "cols: *" (and any shape that does not hold the expected count)
  // made OpenCV allocate a 17 GB matrix while reading K.
  TempDir dir;
  dir.write("huge.yml", "%YAML:1.0\nK: !!opencv-matrix\n   rows: 3\n   cols: 1000000000\n   dt: d\n"
                        "   data: [ 205., 0., 401.5, 0., 204.2, 398., 0., 0., 1. ]\n"
                        "D: !!opencv-matrix\n   rows: 1\n   cols: 4\n   dt: d\n"
                        "   data: [ -0.04, 0.006, 0.0004, -0.0003 ]\nxi: 0.92\n");
  dir.write("cal.yaml", meiWithFile("huge.yml"));
  const std::string what = errorOf([&] { Calibration::load(dir.path() / "cal.yaml"); });
  ASSERT_FALSE(what.empty()) << "expected an error";
  EXPECT_THAT(what, HasSubstr("huge.yml: K: expected 9 numbers"));
  EXPECT_THAT(what, Not(HasSubstr("D:"))) << "D is well-formed: " << what;
}

TEST(Mei, SaveLoadRoundTripInline) {
  TempDir dir;
  const Calibration c = Calibration::parse(kMeiYaml, "cal.yaml");
  c.save(dir.path() / "cal.yaml");
  const Calibration d = Calibration::load(dir.path() / "cal.yaml");
  ASSERT_TRUE(d.omni.mei);
  EXPECT_DOUBLE_EQ(d.omni.mei->s, 0.3);
  EXPECT_NEAR((d.omniPixel(10, 20) - c.omniPixel(10, 20)).norm(), 0.0, 1e-6);
}

// ---------------------------------------------------------------------------------------
// Masks and numeric checks (any model)
// ---------------------------------------------------------------------------------------

TEST(Mask, WrongSizeOrMissingIsNamed) {
  TempDir dir;
  cv::imwrite((dir.path() / "small.png").string(), cv::Mat(100, 100, CV_8UC1, cv::Scalar(255)));
  const std::string linear = "omni: {image_width: 720, image_height: 720, center: [359.5, 359.5], "
                             "radius_inner: 120, radius_outer: 300, mask: MASK}\n"
                             "panorama: {width: 1100, height: 110}\n";
  auto yaml = [&](const std::string& mask) {
    std::string y = linear;
    return y.replace(y.find("MASK"), 4, mask);
  };
  std::string what = parseError(yaml("small.png"), dir.path());
  EXPECT_THAT(what, HasSubstr("omni.mask: small.png is 100x100"));
  EXPECT_THAT(what, HasSubstr("expected 8-bit grey 720x720"));
  what = parseError(yaml("none.png"), dir.path());
  EXPECT_THAT(what, HasSubstr("none.png: cannot read the mask image"));
  cv::imwrite((dir.path() / "good.png").string(), cv::Mat(720, 720, CV_8UC1, cv::Scalar(255)));
  EXPECT_EQ(parseError(yaml("good.png"), dir.path()), "");
}

TEST(NumericFields, NonFiniteAndHugeValuesAreStartUpErrors) {
  const std::string base = "omni: {image_width: 720, image_height: 720, center: [359.5, 359.5], "
                           "radius_inner: 120, radius_outer: RO}\npanorama: {width: PW, height: 110}\n";
  auto yaml = [&](const std::string& ro, const std::string& pw) {
    std::string y = base;
    y.replace(y.find("RO"), 2, ro);
    return y.replace(y.find("PW"), 2, pw);
  };
  std::string what = parseError(yaml(".inf", "1100"), {});
  EXPECT_THAT(what, HasSubstr("omni.radius_outer: must be a finite number"));
  what = parseError(yaml(".nan", "1100"), {});
  EXPECT_THAT(what, HasSubstr("omni.radius_outer: must be a finite number"));
  what = parseError(yaml("300", "1000000000"), {});
  EXPECT_THAT(what, HasSubstr("panorama.width: 1000000000 must be in [1, 16384]"));
}

}  // namespace
}  // namespace omnipose

namespace omnipose {
namespace {

// Found by the calibration.yaml fuzzer (tests/fuzz): a key that is not a plain name threw a
// yaml-cpp conversion error instead of a CalibrationError naming the file.
TEST(CalibrationYaml, KeysThatAreNotPlainNamesAreReportedNotThrown) {
  for (const char* text : {"omni:\n  ? [a]\n  : 1\npanorama: {width: 1100, height: 110}\n",
                           "? {x: 1}\n: 2\nomni: {}\n"}) {
    try {
      Calibration::parse(text, "fuzz.yaml");
      FAIL() << "expected a CalibrationError for:\n" << text;
    } catch (const CalibrationError& e) {
      EXPECT_THAT(e.what(), HasSubstr("fuzz.yaml"));
      EXPECT_THAT(e.what(), HasSubstr("keys must be plain names"));
    }
  }
}

}  // namespace
}  // namespace omnipose

namespace omnipose {
namespace {

std::string fileText(const fs::path& path) {
  std::ifstream in(path);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

int lineCount(const std::string& text) {
  return static_cast<int>(std::count(text.begin(), text.end(), '\n')) + 1;
}

// A hostile calib_results.txt: the real file followed by 150,000 garbled lines (each with a
// NUL and a control character). Every line is a problem; the message lists 20 of them, then
// how many more, escaped and short, and parsing stays fast.
TEST(OcamCalib, GarbledFileGivesABoundedMessage) {
  std::string text = fileText(kOffice);
  for (int i = 0; i < 150'000; ++i) text += std::string("7 gar\0bled\x01", 11) + "\n";
  const auto start = std::chrono::steady_clock::now();
  try {
    OcamCalibModel::parse(text, "calib.txt");
    FAIL() << "expected a ConfigError";
  } catch (const ConfigError& e) {
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_LT(seconds, 5.0);
    const std::string what = e.what();
    EXPECT_EQ(e.problems().size(), 150'000u);
    EXPECT_LE(lineCount(what), 21) << what;
    EXPECT_LT(what.size(), 4096u) << what;
    EXPECT_THAT(what, HasSubstr("'gar\\0bled\\x01' is not a number"));
    EXPECT_THAT(what, HasSubstr("and 149980 more"));
  }
  // Named by calibration.yaml: the same bound, each problem under omni.ocamcalib_file.
  TempDir dir;
  dir.write("garbled.txt", text);
  dir.write("cal.yaml", ocamYaml("garbled.txt"));
  try {
    Calibration::load(dir.path() / "cal.yaml");
    FAIL() << "expected a ConfigError";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_LE(lineCount(what), 22) << what;  // heading, 20 problems, "and N more"
    EXPECT_LT(what.size(), 8192u) << what;
    EXPECT_THAT(what,
                HasSubstr("omni.ocamcalib_file: " + (dir.path() / "garbled.txt").string() + ": line"));
    EXPECT_THAT(what, HasSubstr("more"));
  }
}

TEST(OcamCalib, LongTokenIsEchoedShort) {
  std::string text = fileText(kOffice);
  text += "# ROI\n" + std::string(1'000'000, 'z') + " 1\n";
  try {
    OcamCalibModel::parse(text, "calib.txt");
    FAIL() << "expected a ConfigError";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    EXPECT_LT(what.size(), 512u) << what.substr(0, 1000);
    EXPECT_THAT(what,
                HasSubstr("'" + std::string(60, 'z') + "... (1000000 bytes)' is not a number"))
        << what.substr(0, 1000);
  }
}

}  // namespace
}  // namespace omnipose
