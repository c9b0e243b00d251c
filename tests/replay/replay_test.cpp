// Headless replay end to end: a rendered dataset with a corrupt and a wrong-size frame in
// the middle is replayed; both are skipped, named and counted, the trajectory is right.
#include "replay.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cstdio>
#include <fstream>
#include <optional>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <unistd.h>

#include "bad_images.hpp"
#include "gyro_dataset.hpp"
#include "map/map_file.hpp"
#include "omnipose/eval/evaluation.hpp"
#include "omnipose/synth/synth.hpp"

using ::testing::HasSubstr;

namespace omnipose {
namespace {
namespace fs = std::filesystem;

const fs::path kPhoto = fs::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg";

class ReplayTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    if (!fs::exists(kPhoto)) return;
    // One directory per process: ctest runs the tests of this suite in parallel processes.
    root_ = fs::temp_directory_path() / ("omnipose_replay_test_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    synth::MotionScript script = synth::MotionScript::preset("yaw");
    script.frames = 8;
    const auto poses = synth::generateTrajectory(script);
    synth::RenderOptions ro;
    ro.supersample = 2;
    const synth::Renderer renderer(synth::Scene::load(kPhoto, synth::SceneKind::kSphere),
                                   Calibration{}, ro);
    synth::DatasetWriter writer(root_ / "data", Calibration{}, 0);
    for (const auto& p : poses) writer.addFrame(synth::degrade(renderer.render(p.pose), {}, 0), p);
    writer.finish();
    // Frame 3 becomes unreadable, frame 5 the wrong size.
    std::ofstream(root_ / "data/frames" / writer.frameName(3), std::ios::trunc) << "not a png";
    cv::imwrite((root_ / "data/frames" / writer.frameName(5)).string(),
                cv::Mat(100, 200, CV_8UC1, cv::Scalar(90)));
  }
  void SetUp() override {
    if (!fs::exists(kPhoto)) GTEST_SKIP() << "missing " << kPhoto;
  }
  static void TearDownTestSuite() {
    if (!root_.empty()) fs::remove_all(root_);
  }
  static fs::path root_;
};
fs::path ReplayTest::root_;

TEST_F(ReplayTest, BadFramesAreSkippedNamedAndCountedAndTheRestIsRight) {
  replay::ReplayOptions o;
  o.dataset = root_ / "data";
  o.out_tum = root_ / "est.tum";
  o.relative_csv = root_ / "rel.csv";
  o.progress = false;
  std::FILE* log = std::tmpfile();
  const replay::ReplaySummary s = replay::run(o, log);
  std::rewind(log);
  std::string text(4096, '\0');
  text.resize(std::fread(text.data(), 1, text.size(), log));
  std::fclose(log);

  EXPECT_EQ(s.frames, 8);
  EXPECT_EQ(s.skipped, 2);
  EXPECT_EQ(s.pairs, 5);  // 6 good frames
  EXPECT_GT(s.median_seconds_per_frame, 0.0);
  EXPECT_THAT(text, HasSubstr("000003.png: cannot decode"));
  EXPECT_THAT(text, HasSubstr("000005.png"));
  EXPECT_THAT(text, HasSubstr("200x100, expected 720x720"));

  // Pairs across the skipped frames are missing, the others are accurate.
  const auto result = evaluate(readTum(root_ / "data/groundtruth.tum"), readTum(root_ / "est.tum"));
  EXPECT_EQ(result.pairs_missing, 4);
  EXPECT_EQ(result.pairs.size(), 3u);
  EXPECT_LT(result.angle.max, 1e-3);
  std::ifstream csv(root_ / "rel.csv");
  int lines = 0;
  for (std::string line; std::getline(csv, line);) ++lines;
  EXPECT_EQ(lines, 1 + 5);  // header + one row per pair
}

TEST_F(ReplayTest, BombsTruncatedAndGarbageFramesAreSkippedNamedAndCounted) {
  const fs::path data = root_ / "hostile";
  fs::remove_all(data);
  fs::copy(root_ / "data", data, fs::copy_options::recursive);
  const cv::Mat good = cv::imread((data / "frames/000000.png").string(), cv::IMREAD_UNCHANGED);
  std::vector<testing::BadImageFile> rejected;
  for (auto& f : testing::badImageFiles(good))
    if (f.must_reject) rejected.push_back(std::move(f));
  testing::insertFrames(data, 1, rejected);

  replay::ReplayOptions o;
  o.dataset = data;
  o.out_tum = root_ / "hostile.tum";
  o.progress = false;
  std::FILE* log = std::tmpfile();
  const replay::ReplaySummary s = replay::run(o, log);
  std::rewind(log);
  std::string text(1 << 16, '\0');
  text.resize(std::fread(text.data(), 1, text.size(), log));
  std::fclose(log);

  EXPECT_EQ(s.frames, 8 + static_cast<int>(rejected.size()));
  EXPECT_EQ(s.skipped, 2 + static_cast<int>(rejected.size()));  // and the two of the fixture
  EXPECT_EQ(s.pairs, 5);
  for (const auto& f : rejected) EXPECT_NE(text.find("000001_" + f.name), std::string::npos) << f.name;
  EXPECT_THAT(text, HasSubstr("000001_bomb_60000.png: 60000x60000, expected 720x720"));
  const auto result = evaluate(readTum(data / "groundtruth.tum"), readTum(root_ / "hostile.tum"));
  EXPECT_LT(result.angle.max, 1e-3);
}

TEST_F(ReplayTest, MissingDatasetOrCalibrationIsAClearError) {
  replay::ReplayOptions o;
  o.dataset = root_ / "nope";
  o.progress = false;
  try {
    replay::run(o, stderr);
    FAIL();
  } catch (const std::exception& e) {
    EXPECT_THAT(e.what(), HasSubstr("nope"));
  }
  o.dataset = root_ / "data";
  o.calibration = root_ / "missing.yaml";
  EXPECT_THROW(replay::run(o, stderr), CalibrationError);
  o.calibration.reset();
  o.method = "sift9pt";
  try {
    replay::run(o, stderr);
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(e.what(), HasSubstr("akazerot"));
  }
}

TEST_F(ReplayTest, PartOfTheDatasetAndAMapSavedAndLoaded) {
  replay::ReplayOptions o;
  o.dataset = root_ / "data";
  o.progress = false;
  // The yaw sequence turns 1-6 degrees a frame: places and checks however fast it turns.
  std::ofstream(root_ / "map.yaml") << "loop_closure: {check_interval: 1, max_turn_rate_deg_s: 5000}\n";
  o.config = root_ / "map.yaml";
  o.map_out = root_ / "first.map";
  o.count = 3;
  const replay::ReplaySummary first = replay::run(o, stderr);
  EXPECT_EQ(first.frames, 3) << "--count";
  EXPECT_EQ(first.relocalised_at, -1) << "no map loaded";
  map::MapSnapshot saved;
  ASSERT_TRUE(map::loadMap(root_ / "first.map", Calibration{}, 128, saved));
  EXPECT_EQ(saved.place_count, first.places);
  EXPECT_GE(saved.place_count, 1);

  o.map_out.reset();
  o.map_in = root_ / "first.map";
  o.from = 6;
  o.count = 0;
  o.out_tum = root_ / "restart.tum";
  std::FILE* log = std::tmpfile();
  ASSERT_NE(log, nullptr);
  const replay::ReplaySummary restart = replay::run(o, log);
  std::rewind(log);
  std::string logged;
  for (int c = std::fgetc(log); c != EOF; c = std::fgetc(log))
    logged.push_back(static_cast<char>(c));
  std::fclose(log);
  EXPECT_EQ(restart.frames, 2) << "--from 6: frames 6 and 7";
  // The frames were compared with the loaded map's places, and the log says how it went.
  // (The line is written only when a registration was made.)
  EXPECT_THAT(logged, HasSubstr("map: frames registered against a place ")) << logged;
  EXPECT_THAT(logged, HasSubstr(" look-alike disagreements, ")) << logged;
  const std::vector<StampedPose> poses = readTum(root_ / "restart.tum");
  ASSERT_EQ(poses.size(), 2u);
  const std::vector<StampedPose> truth = readTum(root_ / "data/groundtruth.tum");
  EXPECT_NEAR(poses[0].timestamp, truth[6].timestamp, 1e-6) << "the first pose is frame 6's";

  o.from = 8;
  try {
    replay::run(o, stderr);
    FAIL() << "--from past the end";
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(e.what(), HasSubstr("--from 8: the dataset has 8 frames"));
  }
  o.from = 0;
  std::ofstream(root_ / "notes.txt") << "not a map\n";
  o.map_in = root_ / "notes.txt";
  try {
    replay::run(o, stderr);
    FAIL() << "a file that is not a map";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("--map-in: " + (root_ / "notes.txt").string()));
  }
}

/// A rolling-shutter dataset of a turn on a shaking base with the robot's gyro (imu.csv and the
/// calibration's imu section), rendered once for the suite.
class ReplayGyroTest : public ::testing::Test {
 protected:
  static constexpr int kFrames = 13;  // the start and 12 steps
  static void SetUpTestSuite() {
    if (!fs::exists(kPhoto)) return;
    root_ = fs::temp_directory_path() / ("omnipose_replay_gyro_" + std::to_string(::getpid()));
    fs::remove_all(root_);
    Calibration calibration = testing::writeGyroDataset(root_ / "data", kPhoto, kFrames).calibration;
    calibration.imu.reset();
    calibration.save(root_ / "without_imu.yaml");
  }
  void SetUp() override {
    if (!fs::exists(kPhoto)) GTEST_SKIP() << "missing " << kPhoto;
  }
  static void TearDownTestSuite() {
    if (!root_.empty()) fs::remove_all(root_);
  }
  /// Replays the dataset (with `calibration` when given): the summary, the log, and the
  /// rotation error of the pairs (RMSE, radians).
  static replay::ReplaySummary replay(const std::optional<fs::path>& calibration,
                                      std::string& text, double& rmse) {
    replay::ReplayOptions o;
    o.dataset = root_ / "data";
    o.out_tum = root_ / "est.tum";
    o.calibration = calibration;
    o.progress = false;
    std::FILE* log = std::tmpfile();
    const replay::ReplaySummary s = replay::run(o, log);
    std::rewind(log);
    text.assign(4096, '\0');
    text.resize(std::fread(text.data(), 1, text.size(), log));
    std::fclose(log);
    rmse = evaluate(readTum(root_ / "data/groundtruth.tum"), readTum(root_ / "est.tum")).angle.rmse;
    return s;
  }
  static fs::path root_;
};
fs::path ReplayGyroTest::root_;

TEST_F(ReplayGyroTest, TheDatasetsGyroTakesTheRollingShutterOut) {
  std::string with_text, without_text;
  double with_gyro = 0.0, without_gyro = 0.0;
  const replay::ReplaySummary with = replay(std::nullopt, with_text, with_gyro);
  const replay::ReplaySummary without = replay(root_ / "without_imu.yaml", without_text, without_gyro);
  ::testing::Test::RecordProperty("rotation_rmse_with_gyro", std::to_string(with_gyro));
  ::testing::Test::RecordProperty("rotation_rmse_images_alone", std::to_string(without_gyro));

  EXPECT_EQ(with.pairs, kFrames - 1);
  EXPECT_EQ(with.gyro_frames, kFrames);
  EXPECT_THAT(with_text, HasSubstr("rows' rotations from the gyro in 13 frames"));
  EXPECT_EQ(without.pairs, kFrames - 1);
  EXPECT_EQ(without.gyro_frames, 0);
  // The calibration without an imu section cannot join the gyro's clock to the frames'.
  EXPECT_THAT(without_text, HasSubstr("imu.csv is not used: the calibration has no imu section"));
  EXPECT_LT(with_gyro, 0.5 * without_gyro);
}

}  // namespace
}  // namespace omnipose
