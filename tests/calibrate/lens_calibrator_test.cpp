// The whole calibration (library entry point and the omnipose-calibrate CLI) on a rendered
// turn-left sequence with a known calibration, the panorama proposal, hand overrides and
// errors.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <opencv2/imgcodecs.hpp>

#include "omnipose/calibrate/lens_calibrator.hpp"
#include "synthetic.hpp"
#include "test_files.hpp"

using ::testing::HasSubstr;
using ::testing::Not;

namespace omnipose::calibrate {
namespace {

using namespace omnipose::calibrate::testing;  // synthetic.hpp

constexpr double kPi = std::numbers::pi;

const Provenance* find(const LensCalibrationResult& r, const std::string& key) {
  for (const auto& p : r.provenance)
    if (p.key == key) return &p;
  return nullptr;
}

bool startsWith(const std::string& s, const std::string& prefix) {
  return s.rfind(prefix, 0) == 0;
}

TEST(ProposePanorama, WidthFromCircumferenceHeightSquareAtHorizon) {
  const auto p = proposePanorama(110.0, 230.0, OuterEdge::kTop);
  EXPECT_EQ(p.width, static_cast<int>(std::lround(2 * kPi * 230.0)));  // 1445
  EXPECT_DOUBLE_EQ(p.horizon_radius, 170.0);
  EXPECT_EQ(p.height, static_cast<int>(std::lround(p.width * 120.0 / (2 * kPi * 170.0))));
  EXPECT_DOUBLE_EQ(p.horizon_row, 0.5 * p.height - 0.5);
  // Square at the horizon: one row spans as many pixels radially as one column of arc.
  const double row_px = 120.0 / p.height, col_px = 2 * kPi * 170.0 / p.width;
  EXPECT_NEAR(row_px / col_px, 1.0, 0.01);
}

TEST(ProposePanorama, HorizonRowMapsBackToTheHorizonRadius) {
  for (OuterEdge edge : {OuterEdge::kTop, OuterEdge::kBottom}) {
    const auto p = proposePanorama(100.0, 250.0, edge, 1200, {}, 200.0, 150.0);
    EXPECT_EQ(p.width, 1200);
    // Given the radial scale s: H = W (r_out - r_in) / (2 pi s).
    EXPECT_EQ(p.height, static_cast<int>(std::lround(1200 * 150.0 / (2 * kPi * 150.0))));
    Calibration c;
    c.omni.radius_inner = 100.0;
    c.omni.radius_outer = 250.0;
    c.omni.outer_edge = edge;
    c.panorama.width = p.width;
    c.panorama.height = p.height;
    EXPECT_NEAR(c.radiusOfRow(p.horizon_row), 200.0, 1e-9);
  }
}

/// A known lens, rendered turning left by 5 degrees per frame (park texture when present,
/// tall panorama so the up cue sees sky and grass).
struct Sequence {
  Calibration truth;
  std::vector<cv::Mat> frames;
  bool has_sky = false;
};

Sequence turnLeftSequence(AzimuthDirection dir, OuterEdge edge) {
  Sequence s;
  s.has_sky = std::filesystem::exists(kPark);
  s.truth = makeCalibration(720, 600, 347.6, 318.2, 72.0, 252.0, 35.0, dir, edge,
                            s.has_sky ? 360 : 110);
  for (int k = 0; k < 3; ++k)
    s.frames.push_back(renderOmni(s.has_sky ? kPark : kIndoor, s.truth, 5.0 * k));
  return s;
}

class CalibrateLens : public ::testing::TestWithParam<std::tuple<AzimuthDirection, OuterEdge>> {};

TEST_P(CalibrateLens, RecoversTheRenderersCalibration) {
  const auto [dir, edge] = GetParam();
  const Sequence seq = turnLeftSequence(dir, edge);
  LensCalibratorOptions o;
  o.turn_left = true;
  o.forward_angle_deg = 35.0;
  const auto res = calibrateLens(seq.frames, o);
  std::fputs(res.report().c_str(), stdout);
  const auto& got = res.calibration.omni;
  const auto& want = seq.truth.omni;

  // Circles (centre within 1 px, radii within 2 px).
  ASSERT_TRUE(res.ring);
  EXPECT_LT((res.ring->center - Eigen::Vector2d(want.center_x, want.center_y)).norm(), 1.0);
  EXPECT_NEAR(res.ring->radius_inner, want.radius_inner, 2.0);
  EXPECT_NEAR(res.ring->radius_outer, want.radius_outer, 2.0);
  EXPECT_NEAR(got.center_x, want.center_x, 1.0);
  EXPECT_NEAR(got.center_y, want.center_y, 1.0);
  // The used ring is the edges moved inward by the margins (1 px + 2 x blur; small here).
  EXPECT_DOUBLE_EQ(got.radius_inner, res.ring->radius_inner + res.margin_inner);
  EXPECT_DOUBLE_EQ(got.radius_outer, res.ring->radius_outer - res.margin_outer);
  EXPECT_GE(res.margin_inner, 1.0);
  EXPECT_LE(res.margin_inner, 3.0);
  EXPECT_GE(res.margin_outer, 1.0);
  EXPECT_LE(res.margin_outer, 3.0);

  // Orientation.
  EXPECT_EQ(got.azimuth_direction, want.azimuth_direction);
  ASSERT_TRUE(res.direction);
  EXPECT_TRUE(res.direction->decisive);
  EXPECT_TRUE(startsWith(find(res, "omni.azimuth_direction")->how, "measured"));
  EXPECT_DOUBLE_EQ(got.azimuth_zero_deg, 35.0);
  EXPECT_TRUE(startsWith(find(res, "omni.azimuth_zero_deg")->how, "given"));
  if (seq.has_sky) {
    EXPECT_EQ(got.outer_edge, want.outer_edge);
    EXPECT_TRUE(startsWith(find(res, "omni.outer_edge")->how, "measured"));
  }

  // Panorama proposal.
  EXPECT_EQ(res.calibration.panorama.width,
            static_cast<int>(std::lround(2 * kPi * got.radius_outer)));
  EXPECT_TRUE(res.calibration.validate().empty());

  // Replay: the sequence turns left 5 degrees per frame about z only.
  ASSERT_EQ(res.motions.size(), 2u);
  for (const auto& m : res.motions) {
    ASSERT_TRUE(m.ok) << m.error;
    EXPECT_NEAR(m.omega_deg.z(), 5.0, 0.25);
    EXPECT_LT(std::abs(m.omega_deg.x()), 0.25);
    EXPECT_LT(std::abs(m.omega_deg.y()), 0.25);
  }

  // Every value says how it was determined; the YAML reads back to the same calibration.
  for (const char* key : {"omni.center", "omni.radius_inner", "omni.radius_outer",
                          "omni.azimuth_zero_deg", "omni.azimuth_direction", "omni.outer_edge",
                          "panorama.width", "panorama.height", "panorama.horizon_row"})
    EXPECT_NE(find(res, key), nullptr) << key;
  const Calibration back = Calibration::parse(res.yaml(), "yaml()");
  EXPECT_EQ(back.toYaml(), res.calibration.toYaml());
  EXPECT_THAT(res.yaml(), HasSubstr("# "));
}

INSTANTIATE_TEST_SUITE_P(
    DirectionsAndEdges, CalibrateLens,
    ::testing::Values(std::make_tuple(AzimuthDirection::kCcw, OuterEdge::kTop),
                      std::make_tuple(AzimuthDirection::kCw, OuterEdge::kBottom)),
    [](const auto& info) {
      return std::string(std::get<0>(info.param) == AzimuthDirection::kCw ? "cw" : "ccw") +
             (std::get<1>(info.param) == OuterEdge::kTop ? "_top" : "_bottom");
    });

TEST(CalibrateLensOptions, HandValuesReplaceMeasuredOnes) {
  const Sequence seq = turnLeftSequence(AzimuthDirection::kCcw, OuterEdge::kTop);
  LensCalibratorOptions o;
  o.center = Eigen::Vector2d(347.0, 318.0);
  o.radius_inner = 80.0;
  o.radius_outer = 240.0;
  o.direction = AzimuthDirection::kCw;
  o.outer_edge = OuterEdge::kBottom;
  o.width = 1000;
  o.height = 100;
  o.forward_point = Eigen::Vector2d(347.0, 118.0);  // straight up in the image: 270 degrees
  o.replay = false;
  const auto res = calibrateLens(seq.frames, o);
  const auto& c = res.calibration;
  EXPECT_DOUBLE_EQ(c.omni.center_x, 347.0);
  EXPECT_DOUBLE_EQ(c.omni.radius_inner, 80.0);
  EXPECT_DOUBLE_EQ(c.omni.radius_outer, 240.0);
  EXPECT_EQ(c.omni.azimuth_direction, AzimuthDirection::kCw);
  EXPECT_EQ(c.omni.outer_edge, OuterEdge::kBottom);
  EXPECT_EQ(c.panorama.width, 1000);
  EXPECT_EQ(c.panorama.height, 100);
  EXPECT_NEAR(c.omni.azimuth_zero_deg, 270.0, 1e-9);
  for (const char* key : {"omni.center", "omni.radius_inner", "omni.radius_outer",
                          "omni.azimuth_direction", "omni.outer_edge", "panorama.width",
                          "panorama.height", "omni.azimuth_zero_deg"})
    EXPECT_TRUE(startsWith(find(res, key)->how, "given")) << key << ": " << find(res, key)->how;
  EXPECT_TRUE(res.motions.empty());
}

TEST(CalibrateLensOptions, WithoutTurnSequenceTheDirectionIsAssumedAndSaidSo) {
  const Sequence seq = turnLeftSequence(AzimuthDirection::kCcw, OuterEdge::kTop);
  LensCalibratorOptions o;
  o.outer_edge = OuterEdge::kTop;
  o.replay = false;
  const auto res = calibrateLens(std::span<const cv::Mat>(seq.frames.data(), 1), o);
  EXPECT_EQ(res.calibration.omni.azimuth_direction, AzimuthDirection::kCw);
  EXPECT_TRUE(startsWith(find(res, "omni.azimuth_direction")->how, "assumed"));
  EXPECT_TRUE(startsWith(find(res, "omni.azimuth_zero_deg")->how, "default"));
  EXPECT_DOUBLE_EQ(res.calibration.omni.azimuth_zero_deg, 0.0);
}

TEST(CalibrateLensOptions, Errors) {
  LensCalibratorOptions o;
  EXPECT_THROW(calibrateLens({}, o), std::invalid_argument);
  const std::vector<cv::Mat> mixed = {cv::Mat(100, 100, CV_8UC1, cv::Scalar(0)),
                                      cv::Mat(100, 120, CV_8UC1, cv::Scalar(0))};
  EXPECT_THROW(calibrateLens(mixed, o), std::invalid_argument);
  // No ring anywhere: the message says what to give by hand.
  const std::vector<cv::Mat> blank = {cv::Mat(200, 200, CV_8UC1, cv::Scalar(80))};
  try {
    calibrateLens(blank, o);
    ADD_FAILURE() << "no exception";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("--center"));
  }
  LensCalibratorOptions bad;
  bad.forward_angle_deg = 0;
  bad.forward_point = Eigen::Vector2d(1, 1);
  bad.margin = -1;
  EXPECT_EQ(bad.validate().size(), 2u);
  EXPECT_THROW(calibrateLens(blank, bad), std::invalid_argument);
}

// ------------------------------------------------------------------------------ CLI

const std::filesystem::path kTool = std::filesystem::path(OMNIPOSE_BINARY_DIR) / "bin/omnipose-calibrate";

int run(const std::string& args, const std::filesystem::path& log) {
  const std::string cmd = kTool.string() + " " + args + " > " + log.string() + " 2>&1";
  const int status = std::system(cmd.c_str());
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(CalibrateCli, WritesCalibrationPreviewAndReport) {
  ASSERT_TRUE(std::filesystem::exists(kTool)) << kTool;
  const Sequence seq = turnLeftSequence(AzimuthDirection::kCcw, OuterEdge::kTop);
  const auto dir = std::filesystem::temp_directory_path() / "omnipose_calibrate_cli_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir / "frames");
  for (std::size_t k = 0; k < seq.frames.size(); ++k)
    ASSERT_TRUE(cv::imwrite((dir / "frames" / ("f" + std::to_string(k) + ".png")).string(),
                            seq.frames[k]));
  const auto yaml = dir / "cal.yaml";
  const auto log = dir / "log.txt";
  ASSERT_EQ(run((dir / "frames").string() + " --turn-left --forward-angle 35 --out " +
                    yaml.string(),
                log),
            0)
      << omnipose::testing::readText(log);
  const Calibration cal = Calibration::load(yaml);
  EXPECT_NEAR(cal.omni.center_x, seq.truth.omni.center_x, 1.0);
  EXPECT_NEAR(cal.omni.center_y, seq.truth.omni.center_y, 1.0);
  EXPECT_EQ(cal.omni.azimuth_direction, AzimuthDirection::kCcw);
  EXPECT_TRUE(std::filesystem::exists(dir / "cal_preview.png"));
  const cv::Mat preview = cv::imread((dir / "cal_preview.png").string());
  EXPECT_GT(preview.rows, seq.frames[0].rows);  // donut + panoramas + text
  const std::string report = omnipose::testing::readText(log);
  EXPECT_THAT(report, HasSubstr("omni.azimuth_direction"));
  EXPECT_THAT(report, HasSubstr("measured: turn-left sequence"));
  EXPECT_THAT(report, HasSubstr("yaw"));

  // Usage errors exit with 2, failures with 1.
  EXPECT_EQ(run("--out " + yaml.string(), log), 2);
  EXPECT_EQ(run((dir / "frames").string() + " --out " + yaml.string() + " --direction up", log), 2);
  EXPECT_EQ(run((dir / "missing.png").string() + " --out " + yaml.string(), log), 1);
  std::filesystem::remove_all(dir);
}

/// A file with an image's name that no decoder reads.
void writeGarbage(const std::filesystem::path& file) {
  std::ofstream(file) << "not an image\n";
}

std::string frameName(std::size_t k) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "f%03zu.png", k);
  return buf;
}

TEST(CalibrateCli, UsesAtMostMaxFramesEvenlySpreadAndReadsOnlyThose) {
  ASSERT_TRUE(std::filesystem::exists(kTool)) << kTool;
  const Sequence seq = turnLeftSequence(AzimuthDirection::kCcw, OuterEdge::kTop);
  ASSERT_EQ(seq.frames.size(), 3u);
  const auto dir = std::filesystem::temp_directory_path() / "omnipose_calibrate_max_frames_test";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir / "frames");
  // 21 frames: only 0, 10 and 20 (the 3 an even spread picks) are images; any other one
  // read would be reported as unreadable.
  for (std::size_t k = 0; k <= 20; ++k) {
    const auto file = dir / "frames" / frameName(k);
    if (k % 10 == 0) ASSERT_TRUE(cv::imwrite(file.string(), seq.frames[k / 10]));
    else writeGarbage(file);
  }
  const auto yaml = dir / "cal.yaml";
  const auto log = dir / "log.txt";
  const std::string base = (dir / "frames").string() + " --turn-left --forward-angle 35 --out " +
                           yaml.string();
  {
    SCOPED_TRACE("--max-frames 3 of 21");
    ASSERT_EQ(run(base + " --max-frames 3", log), 0) << omnipose::testing::readText(log);
    const std::string text = omnipose::testing::readText(log);
    EXPECT_THAT(text, HasSubstr("using 3 of 21 frames, every 10.0th"));
    EXPECT_THAT(text, Not(HasSubstr("cannot decode")))
        << "a frame not selected was read:\n" << text;
    EXPECT_THAT(text, HasSubstr("3 frame(s)"));
    const Calibration cal = Calibration::load(yaml);
    EXPECT_NEAR(cal.omni.center_x, seq.truth.omni.center_x, 1.0);
    EXPECT_EQ(cal.omni.azimuth_direction, AzimuthDirection::kCcw);
  }
  {
    // 5 of 21 are 0, 5, 10, 15, 20: the unreadable 5 and 15 are named and skipped.
    SCOPED_TRACE("--max-frames 5 of 21");
    std::filesystem::remove(yaml);
    ASSERT_EQ(run(base + " --max-frames 5", log), 0) << omnipose::testing::readText(log);
    const std::string text = omnipose::testing::readText(log);
    EXPECT_THAT(text, HasSubstr("using 5 of 21 frames"));
    for (std::size_t k = 0; k <= 20; ++k) {
      const bool named = text.find(frameName(k) + ": cannot decode") != std::string::npos;
      EXPECT_EQ(named, k == 5 || k == 15) << frameName(k) << "\n" << text;
    }
    EXPECT_THAT(text, HasSubstr("2 of 5 selected frames could not be read"));
    EXPECT_TRUE(std::filesystem::exists(yaml));
  }
  {
    // The default (60) keeps all 21; the 18 unreadable ones are skipped.
    SCOPED_TRACE("default of 21");
    ASSERT_EQ(run(base, log), 0) << omnipose::testing::readText(log);
    const std::string text = omnipose::testing::readText(log);
    EXPECT_THAT(text, HasSubstr("using all 21 frames"));
    EXPECT_THAT(text, HasSubstr(frameName(1) + ": cannot decode"));
  }
  {
    // None readable: a clear error (exit 1), nothing written.
    SCOPED_TRACE("none readable");
    std::filesystem::create_directories(dir / "bad");
    writeGarbage(dir / "bad" / "a.png");
    writeGarbage(dir / "bad" / "b.png");
    const auto none = dir / "none.yaml";
    EXPECT_EQ(run((dir / "bad").string() + " --out " + none.string(), log), 1);
    const std::string text = omnipose::testing::readText(log);
    EXPECT_THAT(text, HasSubstr("none of the 2 frames selected could be read"));
    EXPECT_FALSE(std::filesystem::exists(none));
  }
  std::filesystem::remove_all(dir);
}

TEST(CalibrateCli, MaxFramesMustBeAWholeNumberInRange) {
  ASSERT_TRUE(std::filesystem::exists(kTool)) << kTool;
  const auto dir = std::filesystem::temp_directory_path() / "omnipose_calibrate_max_frames_flag";
  std::filesystem::create_directories(dir);
  const auto log = dir / "log.txt";
  for (const std::string bad : {"0", "-3", "abc", "2.5", "12x", "501", "99999999999999999999"}) {
    SCOPED_TRACE("--max-frames " + bad);
    EXPECT_EQ(run("frames --out " + (dir / "c.yaml").string() + " --max-frames '" + bad + "'", log), 2);
    const std::string text = omnipose::testing::readText(log);
    EXPECT_THAT(text, HasSubstr("--max-frames"));
    EXPECT_THAT(text, HasSubstr("whole number from 1 to 500"));
  }
  std::filesystem::remove_all(dir);
}

TEST(CalibrateCli, OutputPathsAreCheckedBeforeAnyFrameIsRead) {
  ASSERT_TRUE(std::filesystem::exists(kTool)) << kTool;
  const auto dir = std::filesystem::temp_directory_path() / "omnipose_calibrate_out_check";
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir / "frames");
  // 200 real frames (hard links to one rendered image).
  const Calibration truth = makeCalibration(720, 600, 347.6, 318.2, 72.0, 252.0, 35.0,
                                            AzimuthDirection::kCcw, OuterEdge::kTop, 110);
  const auto first = dir / "frames" / frameName(0);
  ASSERT_TRUE(cv::imwrite(first.string(), renderOmni(kIndoor, truth, 0.0)));
  for (std::size_t k = 1; k < 200; ++k)
    std::filesystem::create_hard_link(first, dir / "frames" / frameName(k));
  const auto log = dir / "log.txt";
  const std::string frames = (dir / "frames").string();
  struct Case {
    std::string args;
    std::string option;  ///< named in the message
    std::string path;    ///< named in the message
  };
  const std::string missing = (dir / "missing" / "cal.yaml").string();
  const std::vector<Case> cases = {
      {frames + " --out " + missing, "--out", missing},
      {frames + " --out " + (dir / "cal.yaml").string() + " --preview " +
           (dir / "nowhere" / "p.png").string(),
       "--preview", (dir / "nowhere" / "p.png").string()},
      {frames + " --out " + (dir / "frames").string(), "--out", "is a directory"},
      {"--propose-mask " + frames + " --out " + (dir / "missing" / "mask.png").string(), "--out",
       (dir / "missing" / "mask.png").string()},
      {"--checkerboard 9x6 --square 0.025 " + frames + " --out " + missing, "--out", missing},
      {"--from-ocamcalib calib_results.txt --out " + missing, "--out", missing},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.args);
    const auto start = std::chrono::steady_clock::now();
    EXPECT_EQ(run(c.args, log), 2);
    const double seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    EXPECT_LT(seconds, 1.0) << "the check must come before the 200 frames are read";
    const std::string text = omnipose::testing::readText(log);
    EXPECT_THAT(text, HasSubstr(c.option));
    EXPECT_THAT(text, HasSubstr(c.path));
    EXPECT_THAT(text, Not(HasSubstr("using "))) << "no frame selection before the check:\n" << text;
  }
  EXPECT_FALSE(std::filesystem::exists(dir / "cal.yaml")) << "nothing written on a failed check";
  EXPECT_FALSE(std::filesystem::exists(dir / "missing"));
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace omnipose::calibrate
