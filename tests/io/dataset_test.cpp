#include "omnipose/io/dataset.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sys/stat.h>

#include <cmath>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

using ::testing::HasSubstr;

namespace omnipose {
namespace {
namespace fs = std::filesystem;

class DatasetTest : public ::testing::Test {
 protected:
  void SetUp() override {
    root_ = fs::temp_directory_path() /
            ("omnipose_dataset_test_" + std::to_string(::testing::UnitTest::GetInstance()->random_seed()) +
             "_" + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(root_);
    fs::create_directories(root_ / "frames");
    Calibration c;
    c.save(root_ / "calibration.yaml");
    for (int i = 0; i < 3; ++i) {
      cv::imwrite((root_ / "frames" / ("f" + std::to_string(2 - i) + ".png")).string(),
                  cv::Mat(720, 720, CV_8UC1, cv::Scalar(100 + i)));
    }
  }
  void TearDown() override { fs::remove_all(root_); }
  fs::path root_;
};

TEST_F(DatasetTest, FramesAreSortedByNameWithDefaultTimestamps) {
  const Dataset d = Dataset::open(root_);
  ASSERT_EQ(d.frames.size(), 3u);
  EXPECT_EQ(d.frames[0].path.filename(), "f0.png");
  EXPECT_EQ(d.frames[2].path.filename(), "f2.png");
  EXPECT_DOUBLE_EQ(d.frames[1].timestamp, 1.0 / 30.0);
  EXPECT_FALSE(d.groundtruth.has_value());
}

TEST_F(DatasetTest, TimestampsFileIsUsedAndAMissingEntryIsNamed) {
  {
    std::ofstream out(root_ / "timestamps.txt");
    out << "# name seconds\nf0.png 10.5\nf1.png 10.6\nf2.png 10.7\n";
  }
  EXPECT_DOUBLE_EQ(Dataset::open(root_).frames[2].timestamp, 10.7);
  {
    std::ofstream out(root_ / "timestamps.txt");
    out << "f0.png 10.5\nf1.png 10.6\n";
  }
  try {
    Dataset::open(root_);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("f2.png"));
  }
}

TEST_F(DatasetTest, AFramesRecordedExposureIsReadAndItsStampMovedToTheCaptureTime) {
  {
    std::ofstream out(root_ / "timestamps.txt");
    out << "f0.png 10.5 0.004\nf1.png 10.6\nf2.png 10.7 0.016\n";
  }
  const Dataset middle = Dataset::open(root_);
  EXPECT_DOUBLE_EQ(middle.frames[0].exposure_s, 0.004);
  EXPECT_TRUE(std::isnan(middle.frames[1].exposure_s)) << "not recorded";
  EXPECT_DOUBLE_EQ(middle.frames[2].exposure_s, 0.016);
  EXPECT_DOUBLE_EQ(middle.frames[2].timestamp, 10.7) << "stamped at the middle: kept";
  // A camera that stamps the end of the first row's exposure (the start of its readout):
  // each stamp moved back by half its own exposure, the calibration's where none is recorded.
  Calibration end;
  end.sensor.stamped_at = StampedAt::kExposureEnd;
  end.sensor.exposure_s = 0.01;
  end.save(root_ / "calibration.yaml");
  const Dataset d = Dataset::open(root_);
  EXPECT_DOUBLE_EQ(d.frames[0].timestamp, 10.5 - 0.002);
  EXPECT_DOUBLE_EQ(d.frames[1].timestamp, 10.6 - 0.005);
  EXPECT_DOUBLE_EQ(d.frames[2].timestamp, 10.7 - 0.008);
  Calibration start = end;
  start.sensor.stamped_at = StampedAt::kExposureStart;
  start.save(root_ / "calibration.yaml");
  EXPECT_DOUBLE_EQ(Dataset::open(root_).frames[2].timestamp, 10.7 + 0.008);
  // An exposure that is not a number of seconds in [0, 10] names its line.
  for (const char* bad : {"-0.001", "11", "nan", "1/30", "0x1p-6"}) {
    {
      std::ofstream out(root_ / "timestamps.txt");
      out << "f0.png 10.5\nf1.png 10.6 " << bad << "\nf2.png 10.7\n";
    }
    try {
      Dataset::open(root_);
      ADD_FAILURE() << bad << " accepted";
    } catch (const std::runtime_error& e) {
      EXPECT_THAT(e.what(), HasSubstr("timestamps.txt:2: exposure '")) << bad;
    }
  }
}

TEST_F(DatasetTest, TimestampsBeyondTenBillionSecondsAreRefusedNamingTheLine) {
  {
    std::ofstream out(root_ / "timestamps.txt");
    out << "f0.png 0.0\nf1.png 1e300\nf2.png 0.2\n";
  }
  try {
    Dataset::open(root_);
    ADD_FAILURE() << "1e300 s accepted (pacing converts it to integer microseconds)";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("timestamps.txt:2: timestamp must be a finite number"));
  }
}

TEST_F(DatasetTest, MissingPiecesAreClearErrors) {
  EXPECT_THROW(Dataset::open(root_ / "nope"), std::runtime_error);
  fs::remove(root_ / "calibration.yaml");
  try {
    Dataset::open(root_);
    FAIL();
  } catch (const CalibrationError& e) {
    EXPECT_THAT(e.what(), HasSubstr("calibration.yaml"));
  }
}

TEST_F(DatasetTest, CorruptAndMissingImagesAreNamed) {
  const fs::path bad = root_ / "frames" / "f9.png";
  {
    std::ofstream out(bad);
    out << "this is not a png";
  }
  auto frame = readFrame(bad);
  ASSERT_FALSE(frame.has_value());
  EXPECT_EQ(frame.error().code(), ErrorCode::kBadFrame);
  EXPECT_THAT(frame.error().message(), HasSubstr("f9.png"));
  auto missing = readFrame(root_ / "frames" / "nothing.png");
  ASSERT_FALSE(missing.has_value());
  EXPECT_EQ(missing.error().code(), ErrorCode::kNotFound);
}

TEST(Trajectory, TumRoundTripAndMalformedLine) {
  const fs::path path = fs::temp_directory_path() / "omnipose_traj_test.tum";
  std::vector<StampedPose> poses(2);
  poses[1].timestamp = 0.25;
  poses[1].pose.linear() = rotationFromVector(Eigen::Vector3d(0.1, 0.2, -0.3));
  poses[1].pose.translation() = Eigen::Vector3d(1, -2, 3);
  writeTum(path, poses);
  const auto back = readTum(path);
  ASSERT_EQ(back.size(), 2u);
  EXPECT_DOUBLE_EQ(back[1].timestamp, 0.25);
  EXPECT_TRUE(back[1].pose.isApprox(poses[1].pose, 1e-8));
  {
    std::ofstream out(path, std::ios::app);
    out << "0.5 1 2 3\n";
  }
  try {
    readTum(path);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr(":4:"));
  }
  fs::remove(path);
}


/// The message of Dataset::open()'s error for the dataset as it is.
std::string openError(const fs::path& root) {
  try {
    Dataset::open(root);
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return "(opened)";
}

TEST_F(DatasetTest, TimestampsThatAreNotPlainDecimalsOrNameAFrameTwiceAreErrorsNamingTheLine) {
  struct Case {
    std::string text;
    std::string says;
  };
  const std::vector<Case> cases = {
      {"f0.png 1\nf1.png 2\nf2.png 0x1p3\n", "timestamps.txt:3: '0x1p3' is not a decimal number"},
      {"f0.png 1\nf1.png inf\nf2.png 3\n", "timestamps.txt:2: 'inf' is not a decimal number"},
      {"f0.png nan\nf1.png 2\nf2.png 3\n", "timestamps.txt:1: 'nan' is not a decimal number"},
      {"f0.png 1e400\nf1.png 2\nf2.png 3\n", "timestamps.txt:1: '1e400' is not a decimal number"},
      {"f0.png 1\nf1.png 2\nf2.png 3\nf1.png 4\n", "timestamps.txt:4: f1.png given twice (first on line 2)"},
      {"f0.png 1\nf1.png\nf2.png 3\n", "timestamps.txt:2: expected '<file name> <seconds>'"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.text);
    std::ofstream(root_ / "timestamps.txt") << c.text;
    const std::string what = openError(root_);
    EXPECT_THAT(what, HasSubstr(c.says));
  }
  std::ofstream(root_ / "timestamps.txt") << "f0.png +1.5\nf1.png 2.\nf2.png .25e1\n";
  const Dataset d = Dataset::open(root_);
  EXPECT_DOUBLE_EQ(d.frames[0].timestamp, 1.5);
  EXPECT_DOUBLE_EQ(d.frames[1].timestamp, 2.0);
  EXPECT_DOUBLE_EQ(d.frames[2].timestamp, 2.5);
  EXPECT_TRUE(d.warnings.empty());
}

TEST_F(DatasetTest, NegativeAndBackwardsTimesAreWarningsNamingTheLine) {
  std::ofstream(root_ / "timestamps.txt") << "# t\nf0.png -2\nf1.png -1\nf2.png -1.5\n";
  const Dataset d = Dataset::open(root_);
  ASSERT_EQ(d.warnings.size(), 4u);
  EXPECT_THAT(d.warnings[0], HasSubstr("timestamps.txt:2: f0.png at -2.000000 s: a negative time"));
  EXPECT_THAT(d.warnings[3],
              HasSubstr("timestamps.txt:4: f2.png at -1.500000 s is not after the frame before "
                        "it (f1.png at -1.000000 s)"));
  // All equal: one warning per frame, at most 20 and then a count.
  fs::remove_all(root_ / "frames");
  fs::create_directories(root_ / "frames");
  std::ofstream stamps(root_ / "timestamps.txt");
  for (int i = 0; i < 30; ++i) {
    const std::string name = "g" + std::to_string(100 + i) + ".png";
    cv::imwrite((root_ / "frames" / name).string(), cv::Mat(720, 720, CV_8UC1, cv::Scalar(9)));
    stamps << name << " 7\n";
  }
  stamps.close();
  const Dataset equal = Dataset::open(root_);
  ASSERT_EQ(equal.warnings.size(), 21u);
  EXPECT_EQ(equal.warnings.back(), "and 9 more timestamp warnings");
}

TEST_F(DatasetTest, TextFilesThatAreDevicesOrFifosAreRefusedByNameWithoutReading) {
  fs::create_symlink("/dev/zero", root_ / "timestamps.txt");
  std::string what = openError(root_);
  EXPECT_THAT(what, HasSubstr("timestamps.txt: not a regular file (a character device)"));
  fs::remove(root_ / "timestamps.txt");
  ASSERT_EQ(::mkfifo((root_ / "timestamps.txt").c_str(), 0600), 0);
  what = openError(root_);
  EXPECT_THAT(what, HasSubstr("timestamps.txt: not a regular file (a FIFO)"));
  fs::remove(root_ / "timestamps.txt");
  fs::create_symlink("/dev/zero", root_ / "groundtruth.tum");
  what = openError(root_);
  EXPECT_THAT(what, HasSubstr("groundtruth.tum: not a regular file (a character device)"));
  fs::remove(root_ / "groundtruth.tum");
  fs::remove(root_ / "calibration.yaml");
  fs::create_directory(root_ / "calibration.yaml");
  what = openError(root_);
  EXPECT_THAT(what, HasSubstr("calibration.yaml: not a regular file (a directory)"));
}

TEST_F(DatasetTest, GroundTruthValuesMustBePlainFiniteDecimals) {
  std::ofstream(root_ / "groundtruth.tum") << "0 0 0 0 0 0 0 1\n0.1 0x1 0 0 0 0 0 1\n";
  const std::string what = openError(root_);
  EXPECT_THAT(what, HasSubstr("groundtruth.tum:2: every value must be a finite decimal number"));
}

}  // namespace
}  // namespace omnipose
