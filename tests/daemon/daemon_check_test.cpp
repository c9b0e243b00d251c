// omniposed --check: the calibration and what it names (lens model, mask) and the
// pipeline against it are validated without opening a camera; every problem is a non-zero
// exit naming the file and the field.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>

#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "daemon/startup_check.hpp"
#include "daemon_test_support.hpp"
#include "omnipose/calibration.hpp"

using ::testing::HasSubstr;
using ::testing::Not;

namespace omnipose {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using testing::TempDir;

fs::path omniposed() { return testing::binaryDir() / "omniposed"; }

std::string lines(const std::vector<std::string>& v) {
  std::string out;
  for (const auto& s : v) out += s + "\n";
  return out;
}

/// A dataset directory with a calibration and one frame's name (the check lists the frames
/// and reads the recording's text files, it decodes no frame).
struct CheckCase {
  TempDir tmp{"check"};
  fs::path dataset() const { return tmp / "data"; }
  int run(const Calibration& c) {
    fs::create_directories(dataset() / "frames");
    testing::writeText(dataset() / "frames/000000.png", "");
    c.save(dataset() / "calibration.yaml");
    testing::writeText(tmp / "daemon.yaml", testing::fileSourceConfig(dataset(), "memq://", false));
    return testing::runProcess({omniposed().string(), "--config", (tmp / "daemon.yaml").string(), "--check"},
                               tmp / "out", tmp / "err", 60s);
  }
  std::string err() const { return testing::readText(tmp / "err"); }
};

TEST(DaemonCheck, AnOcamCalibLensWithAMaskPasses) {
  CheckCase t;
  Calibration c = Calibration::parse(
      "omni:\n  model: ocamcalib\n  ocamcalib_file: steep_mirror_800_ocamcalib.txt\n"
      "panorama: {width: 1100, height: 110}\n",
      "cal.yaml", fs::path(OMNIPOSE_SOURCE_DIR) / "tests/data/catadioptric");
  c.omni.mask = cv::Mat(800, 800, CV_8UC1, cv::Scalar(255));
  c.omni.mask_file = "mask.png";
  EXPECT_EQ(t.run(c), 0) << t.err();
  EXPECT_THAT(t.err(), HasSubstr("lens model ocamcalib with a mask, panorama 1100x110: usable"));
}

TEST(DaemonCheck, AMaskOfTheWrongSizeFailsNamingTheFile) {
  CheckCase t;
  Calibration c;
  c.omni.mask = cv::Mat(720, 720, CV_8UC1, cv::Scalar(255));
  c.omni.mask_file = "mask.png";
  fs::create_directories(t.dataset());
  ASSERT_EQ(t.run(c), 0) << t.err();
  cv::imwrite((t.dataset() / "mask.png").string(), cv::Mat(10, 10, CV_8UC1, cv::Scalar(0)));
  EXPECT_EQ(testing::runProcess({omniposed().string(), "--config", (t.tmp / "daemon.yaml").string(), "--check"},
                                t.tmp / "out", t.tmp / "err", 60s),
            1);
  EXPECT_THAT(t.err(), HasSubstr("omni.mask: mask.png is 10x10"));
}

TEST(DaemonCheck, AMaskThatLeavesTooFewWindowsFailsSayingHowManyAreLeft) {
  // Everything masked but a 15-degree sector: fewer than 4 of the 55 windows keep enough usable pixels;
  // the daemon would otherwise start and lose every frame.
  CheckCase t;
  Calibration c;
  cv::Mat mask(720, 720, CV_8UC1, cv::Scalar(0));
  cv::ellipse(mask, {360, 360}, {360, 360}, 0, 0, 15, cv::Scalar(255), cv::FILLED);
  c.omni.mask = mask;
  c.omni.mask_file = "mask.png";
  EXPECT_EQ(t.run(c), 1) << t.err();
  EXPECT_THAT(t.err(), HasSubstr("windows measurable; the fit needs at least 4"));
  // The same mask over half the ring starts.
  cv::ellipse(mask, {360, 360}, {360, 360}, 0, 0, 180, cv::Scalar(255), cv::FILLED);
  c.omni.mask = mask;
  EXPECT_EQ(t.run(c), 0) << t.err();
}

TEST(DaemonCheck, TheListingShowsAtMostTwentyProblemsEscaped) {
  daemon::StartupCheck check;
  for (int i = 0; i < 25; ++i) check.problems.push_back("cal.yaml: key" + std::to_string(i) + ": bad");
  check.problems[0] += std::string("\0hidden", 7);
  const std::string listing = check.listing();
  EXPECT_EQ(std::count(listing.begin(), listing.end(), '\n'), 20) << listing;
  EXPECT_THAT(listing, HasSubstr("key19: bad"));
  EXPECT_THAT(listing, Not(HasSubstr("key20: bad")));
  EXPECT_THAT(listing, HasSubstr("and 5 more"));
  EXPECT_THAT(listing, HasSubstr("bad\\0hidden"));
}

TEST(DaemonCheck, APanoramaLowerThanTheWindowFails) {
  CheckCase t;
  Calibration c;
  c.panorama.height = 80;
  c.panorama.horizon_row = 39.5;
  EXPECT_EQ(t.run(c), 1);
  EXPECT_THAT(t.err(),
              HasSubstr("daemon.yaml: pipeline.window: 110 is larger than the "
                        "panorama (1100 x 80)"));
}

TEST(DaemonCheck, EveryProblemIsListedAtOnceByTheKeyTheUserWrote) {
  TempDir tmp("check_all");
  Calibration c;
  c.panorama.height = 80;
  c.panorama.horizon_row = 39.5;
  c.save(tmp / "calibration.yaml");
  const DaemonConfig config = DaemonConfig::parse(
      "source: {type: file, path: no_such_dataset}\ncalibration: calibration.yaml\n"
      "pipeline: {window: 100}\nscheduling: {cpus: [4000]}\n",
      (tmp / "daemon.yaml").string(), tmp.path());
  const daemon::StartupCheck check = daemon::checkStartup(config);
  ASSERT_EQ(check.problems.size(), 3u) << lines(check.problems);
  EXPECT_THAT(check.problems[0], HasSubstr("daemon.yaml: source.path: "));
  EXPECT_THAT(check.problems[0], HasSubstr("no_such_dataset is not a directory"));
  EXPECT_THAT(check.problems[1],
              HasSubstr("daemon.yaml: scheduling.cpus: CPU 4000 does not exist"));
  EXPECT_THAT(check.problems[2],
              HasSubstr("daemon.yaml: pipeline.window: 100 is larger than the "
                        "panorama (1100 x 80)"));

  // Fixed: the check builds the pipeline and reports what it found usable.
  fs::create_directories(tmp / "no_such_dataset/frames");
  testing::writeText(tmp / "no_such_dataset/frames/000000.png", "");
  c.panorama.height = 110;
  c.panorama.horizon_row = 54.5;
  c.save(tmp / "calibration.yaml");
  const daemon::StartupCheck fixed = daemon::checkStartup(DaemonConfig::parse(
      "source: {type: file, path: no_such_dataset}\ncalibration: calibration.yaml\n",
      (tmp / "daemon.yaml").string(), tmp.path()));
  EXPECT_TRUE(fixed.problems.empty()) << lines(fixed.problems);
  ASSERT_EQ(fixed.findings.size(), 4u) << lines(fixed.findings);
  EXPECT_EQ(fixed.findings[3], "scheduling: normal scheduling on every CPU");
  EXPECT_THAT(fixed.findings[1], HasSubstr("no_such_dataset: 1 frames"));
  EXPECT_THAT(fixed.findings[2], HasSubstr("lens model linear, panorama 1100x110: usable"));
}

TEST(DaemonCheck, TheMapFileIsDescribedAndADirectoryThatIsNotThereIsAProblem) {
  TempDir tmp("check_map");
  Calibration{}.save(tmp / "calibration.yaml");
  fs::create_directories(tmp / "d/frames");
  testing::writeText(tmp / "d/frames/000000.png", "");
  const auto check = [&](const std::string& map_file) {
    return daemon::checkStartup(DaemonConfig::parse(
        "source: {type: file, path: d}\ncalibration: calibration.yaml\n"
        "loop_closure: {map_file: " + map_file + "}\n",
        (tmp / "daemon.yaml").string(), tmp.path()));
  };
  const auto missing_dir = check("no_such_dir/robot.map");
  ASSERT_EQ(missing_dir.problems.size(), 1u) << lines(missing_dir.problems);
  EXPECT_THAT(missing_dir.problems[0],
              HasSubstr("loop_closure.map_file: " + (tmp / "no_such_dir/robot.map").string() +
                        ": its directory does not exist"));
  const auto none_yet = check("robot.map");
  EXPECT_TRUE(none_yet.problems.empty()) << lines(none_yet.problems);
  EXPECT_THAT(lines(none_yet.findings), HasSubstr("robot.map: none yet; written while running"));
  testing::writeText(tmp / "notes.txt", "not a map");
  const auto foreign = check("notes.txt");
  EXPECT_TRUE(foreign.problems.empty()) << "the daemon starts, with an empty map";
  EXPECT_THAT(lines(foreign.findings), HasSubstr("the daemon would start with an empty map"));
}

TEST(DaemonCheck, CameraOptionsAreCheckedWithoutOpeningTheDevice) {
  TempDir tmp("check_v4l2");
  Calibration{}.save(tmp / "calibration.yaml");
  auto check = [&](const std::string& source) {
    return daemon::checkStartup(DaemonConfig::parse(
        "source: " + source + "\ncalibration: calibration.yaml\n", (tmp / "daemon.yaml").string(),
        tmp.path()));
  };
  // A device that does not exist: --check does not open it, so only the options count.
  const auto bad = check("{type: v4l2, device: /dev/no_such_video, format: RGB3}");
  ASSERT_EQ(bad.problems.size(), 1u) << lines(bad.problems);
  EXPECT_THAT(bad.problems[0],
              HasSubstr("daemon.yaml: source.format: 'RGB3' is not a V4L2 format"));
  const auto good = check("{type: v4l2, device: /dev/no_such_video, format: GREY}");
  EXPECT_TRUE(good.problems.empty()) << lines(good.problems);
  ASSERT_FALSE(good.findings.empty());
  EXPECT_THAT(good.findings[0],
              HasSubstr("source: v4l2 /dev/no_such_video, 1280x720 GREY: options valid"));
}

// A gyro: the calibration's imu section is needed (lcm and iio alike), and an IIO device
// that is not there is named, without anything being opened.
TEST(DaemonCheck, AGyroNeedsTheCalibrationsImuSectionAndAnIioDeviceThatIsThere) {
  TempDir tmp("check_imu");
  fs::create_directories(tmp / "data/frames");
  testing::writeText(tmp / "data/frames/000000.png", "");
  Calibration c;
  c.save(tmp / "calibration.yaml");
  auto check = [&](const std::string& imu) {
    return daemon::checkStartup(DaemonConfig::parse(
        "source: {type: file, path: data}\ncalibration: calibration.yaml\nimu: " + imu + "\n",
        (tmp / "daemon.yaml").string(), tmp.path()));
  };
  const auto lcm = check("{source: lcm, url: \"memq://\"}");
  ASSERT_EQ(lcm.problems.size(), 1u) << lines(lcm.problems);
  EXPECT_THAT(lcm.problems[0], HasSubstr("daemon.yaml: imu.source: lcm needs the calibration's imu "
                                         "section (" + (tmp / "calibration.yaml").string()));
  const auto iio = check("{source: iio, device: no_such_gyro}");
  ASSERT_EQ(iio.problems.size(), 2u) << lines(iio.problems);
  EXPECT_THAT(iio.problems[0], HasSubstr("daemon.yaml: imu.device: iio device \"no_such_gyro\""));
  EXPECT_THAT(iio.problems[1], HasSubstr("imu.source: iio needs the calibration's imu section"));

  c.imu = ImuCalibration{};
  c.save(tmp / "calibration.yaml");
  const auto fixed = check("{source: lcm, url: \"memq://\"}");
  EXPECT_TRUE(fixed.problems.empty()) << lines(fixed.problems);
}

}  // namespace
}  // namespace omnipose
