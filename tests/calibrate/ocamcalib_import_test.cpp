// omnipose-calibrate --from-ocamcalib: a calibration for an OCamCalib lens that
// the pipeline accepts, or a refusal that says what to change.
#include "omnipose/calibrate/ocamcalib_import.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sys/wait.h>

#include "omnipose/io/trajectory.hpp"
#include "omnipose/synth/synth.hpp"
#include "test_files.hpp"

using ::testing::HasSubstr;

namespace omnipose::calibrate {
namespace {

namespace fs = std::filesystem;
const fs::path kOffice = fs::path(OMNIPOSE_SOURCE_DIR) / "tests/data/catadioptric/mirror_office_ocamcalib.txt";

std::string errorOf(const fs::path& file, const ModelImportOptions& o) {
  try {
    importOcamCalib(file, o);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "";
}

TEST(OcamCalibImport, RealFileGivesAValidCalibrationInsideTheRing) {
  const ModelImport r = importOcamCalib(kOffice, {});
  const Calibration& c = r.calibration;
  EXPECT_TRUE(c.validate().empty());
  EXPECT_EQ(c.omni.model, LensModelKind::kOcamCalib);
  EXPECT_DOUBLE_EQ(c.omni.radius_inner, 235.0);
  EXPECT_DOUBLE_EQ(c.omni.radius_outer, 600.0);
  EXPECT_EQ(c.panorama.width, 1100);
  EXPECT_EQ(c.panorama.height, 110);
  EXPECT_DOUBLE_EQ(c.panorama.horizon_row, 54.5);  // +-17 deg fits: horizon in the middle
  // It says what it assumed.
  bool assumed = false;
  for (const auto& n : r.notes) assumed |= n.find("ASSUMED") != std::string::npos;
  EXPECT_TRUE(assumed);
}

TEST(OcamCalibImport, TallPanoramaMovesTheHorizonToFit) {
  ModelImportOptions o;
  o.width = 1440;
  o.height = 240;
  const Calibration c = importOcamCalib(kOffice, o).calibration;
  EXPECT_TRUE(c.validate().empty());
  // 240 rows centred would span +-27.6 deg, but the ring (1 deg margin) reaches only
  // +25.1: the horizon moves up (to a smaller row) and the bottom edge stays inside too.
  EXPECT_LT(c.panorama.horizon_row, 119.5);
  const auto [e_in, e_out] = c.ringElevations();
  EXPECT_LE(std::atan(c.panorama.cylinderHeight(-0.5)), e_out);
  EXPECT_GE(std::atan(c.panorama.cylinderHeight(239.5)), e_in);
}

TEST(OcamCalibImport, PanoramaTooTallForTheRingIsRefusedWithAHint) {
  ModelImportOptions o;
  o.height = 400;
  const std::string what = errorOf(kOffice, o);
  EXPECT_THAT(what, HasSubstr("mirror_office_ocamcalib.txt: a 1100 x 400 panorama does not fit"));
  EXPECT_THAT(what, HasSubstr("lower --height or --width"));
}

TEST(OcamCalibImport, NoRoiLineNeedsTheRing) {
  const fs::path dir = fs::temp_directory_path() / ("omnipose_ocam_import_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::string s = omnipose::testing::readText(kOffice);
  s = s.substr(0, s.find("#ROI"));
  std::ofstream(dir / "noroi.txt") << s;
  const std::string what = errorOf(dir / "noroi.txt", {});
  EXPECT_THAT(what,
              HasSubstr("noroi.txt: has no ROI line: give the used ring with --radius-inner"));
  ModelImportOptions o;
  o.radius_inner = 250;
  o.radius_outer = 560;
  const Calibration c = importOcamCalib(dir / "noroi.txt", o).calibration;
  EXPECT_DOUBLE_EQ(c.omni.radius_outer, 560.0);
  EXPECT_EQ(c.omni.image_width, 1300);  // no crop line: the calibrated size
  fs::remove_all(dir);
}

// The tool's quality gate: a panorama the default pipeline would refuse (lower than its
// 110-pixel window) is not written; exit code 1 and the reason on stderr.
TEST(OcamCalibImportCli, RefusesWhatReplayWouldRefuse) {
  const fs::path tool = fs::path(OMNIPOSE_BINARY_DIR) / "bin/omnipose-calibrate";
  const fs::path dir = fs::temp_directory_path() / ("omnipose_ocam_cli_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const std::string base = tool.string() + " --quiet --from-ocamcalib " + kOffice.string() + " --out " +
                           (dir / "cal.yaml").string();
  int status = std::system((base + " --height 80 2> " + (dir / "err.txt").string()).c_str());
  EXPECT_EQ(WEXITSTATUS(status), 1);
  EXPECT_FALSE(fs::exists(dir / "cal.yaml"));
  const std::string err = omnipose::testing::readText(dir / "err.txt");
  EXPECT_THAT(err, HasSubstr("registration.window: 110 is larger than the panorama (1100 x 80)"));
  status = std::system(base.c_str());
  EXPECT_EQ(WEXITSTATUS(status), 0);
  EXPECT_TRUE(fs::exists(dir / "cal.yaml"));
  EXPECT_TRUE(fs::exists(dir / "mirror_office_ocamcalib.txt"));
  EXPECT_NO_THROW(Calibration::load(dir / "cal.yaml"));
  fs::remove_all(dir);
}

// A mirrored capture flips the azimuth direction: a turn-left sequence measures it.
TEST(OcamCalibImport, TurnLeftSequenceMeasuresTheDirection) {
  const fs::path steep = fs::path(OMNIPOSE_SOURCE_DIR) / "tests/data/catadioptric/steep_mirror_800_ocamcalib.txt";
  const fs::path photo = fs::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg";
  for (const auto truth : {AzimuthDirection::kCw, AzimuthDirection::kCcw}) {
    ModelImportOptions given;
    given.direction = truth;
    const Calibration rendered = importOcamCalib(steep, given).calibration;
    const synth::Renderer renderer(synth::Scene::load(photo, synth::SceneKind::kSphere), rendered,
                                   {synth::OutputKind::kOmni, 1});
    std::vector<cv::Mat> frames;
    for (int k = 0; k < 3; ++k) {
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.linear() = rotationFromVector(Eigen::Vector3d(0, 0, 0.06 * k));  // turning left
      cv::Mat f;
      renderer.render(T).convertTo(f, CV_8U);
      frames.push_back(f);
    }
    ModelImportOptions measure;
    measure.turn_left = true;
    const ModelImport r = importOcamCalib(steep, measure, frames);
    EXPECT_EQ(r.calibration.omni.azimuth_direction, truth);
    bool measured = false;
    for (const auto& n : r.notes) measured |= n.find("measured from the turn-left sequence") != std::string::npos;
    EXPECT_TRUE(measured);
  }
  // Without motion it refuses instead of guessing.
  ModelImportOptions measure;
  measure.turn_left = true;
  const std::vector<cv::Mat> still(3, cv::Mat(800, 800, CV_8UC1, cv::Scalar(90)));
  EXPECT_THROW(importOcamCalib(steep, measure, still), std::runtime_error);
}

}  // namespace
}  // namespace omnipose::calibrate
