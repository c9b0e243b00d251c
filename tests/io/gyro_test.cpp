// imu.csv, the recorded gyro of a dataset: the columns found by their names in any order and
// with others beside them, every sample's time and rate read exactly, the sampling interval
// and the gaps measured, and every malformed input refused with a message naming the file,
// the line and what is wrong.
#include "omnipose/io/gyro.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

#include <unistd.h>

using ::testing::HasSubstr;

namespace omnipose {
namespace {

/// The message parseGyroCsv throws for `text` (empty when it parses).
std::string errorOf(const std::string& text) {
  try {
    parseGyroCsv(text, "imu.csv");
  } catch (const std::runtime_error& e) {
    return e.what();
  }
  return {};
}

TEST(GyroCsv, ReadsTheNamedColumnsInAnyOrderAndIgnoresTheOthers) {
  const GyroRecording r = parseGyroCsv(
      "# recorded on the robot\n"
      "ax, wz ,t,wy,wx,temperature\n"
      "9.81,0.25,12.000,-0.5,0.125,31.5\n"
      "\n"
      "9.80, -0.25 ,12.005,0.5,-0.125,31.5\r\n",
      "imu.csv");
  ASSERT_EQ(r.samples.size(), 2u);
  EXPECT_EQ(r.samples[0].t, 12.0);
  EXPECT_EQ(r.samples[0].rate, Eigen::Vector3d(0.125, -0.5, 0.25));
  EXPECT_EQ(r.samples[1].t, 12.005);
  EXPECT_EQ(r.samples[1].rate, Eigen::Vector3d(-0.125, 0.5, -0.25));
}

TEST(GyroCsv, MeasuresTheSamplingIntervalAndTheGaps) {
  // 200 Hz with one hole of 50 ms (ten intervals) and one of 20 ms (four: not a gap).
  std::string text = "t,wx,wy,wz\n";
  double t = 0.0;
  for (int k = 0; k < 100; ++k) {
    t += k == 40 ? 0.050 : k == 70 ? 0.020 : 0.005;
    text += std::to_string(t) + ",0,0,0.1\n";
  }
  const GyroRecording r = parseGyroCsv(text, "imu.csv");
  EXPECT_EQ(r.samples.size(), 100u);
  EXPECT_NEAR(r.median_interval_s, 0.005, 1e-9);
  EXPECT_EQ(r.gaps, 1);
  EXPECT_NEAR(r.longest_gap_s, 0.050, 1e-9);
}

TEST(GyroCsv, OneSampleHasNoInterval) {
  const GyroRecording r = parseGyroCsv("t,wx,wy,wz\n1,0,0,0\n", "imu.csv");
  ASSERT_EQ(r.samples.size(), 1u);
  EXPECT_EQ(r.median_interval_s, 0.0);
  EXPECT_EQ(r.gaps, 0);
  EXPECT_EQ(r.longest_gap_s, 0.0);
}

TEST(GyroCsv, EveryMalformedInputIsRefusedByFileLineAndWhat) {
  const std::string header = "t,wx,wy,wz\n";
  EXPECT_EQ(errorOf(""), "imu.csv: no header (t,wx,wy,wz) and no samples");
  EXPECT_EQ(errorOf("# only a comment\n\n"), "imu.csv: no header (t,wx,wy,wz) and no samples");
  EXPECT_EQ(errorOf(header), "imu.csv: no samples");
  EXPECT_THAT(errorOf("t,wx,wy\n1,0,0\n"),
              HasSubstr("imu.csv:1: the header must name the columns t, wx, wy and wz (wz is missing)"));
  EXPECT_THAT(errorOf("1.0,0,0,0\n"), HasSubstr("imu.csv:1: the header must name"));
  EXPECT_THAT(errorOf("t,wx,wy,wz,wx\n"), HasSubstr("imu.csv:1: column 'wx' is named twice"));
  EXPECT_THAT(errorOf(header + "1,0,0\n"), HasSubstr("imu.csv:2: 3 fields, the header has 4"));
  EXPECT_THAT(errorOf(header + "1,0,0,0,0\n"), HasSubstr("imu.csv:2: 5 fields, the header has 4"));
  EXPECT_THAT(errorOf(header + "1,nan,0,0\n"),
              HasSubstr("imu.csv:2: wx: 'nan' is not a finite decimal number"));
  EXPECT_THAT(errorOf(header + "1,0,inf,0\n"), HasSubstr("imu.csv:2: wy: 'inf' is not"));
  EXPECT_THAT(errorOf(header + "1,0,0,1e999\n"), HasSubstr("imu.csv:2: wz: '1e999' is not"));
  EXPECT_THAT(errorOf(header + "0x1p3,0,0,0\n"), HasSubstr("imu.csv:2: t: '0x1p3' is not"));
  EXPECT_THAT(errorOf(header + "1,,0,0\n"), HasSubstr("imu.csv:2: wx: '' is not"));
  EXPECT_THAT(errorOf(header + "1,0,-250,0\n"),
              HasSubstr("imu.csv:2: wy: -250 rad/s is beyond any gyro's range (100 rad/s)"));
  EXPECT_EQ(errorOf(header + "1,100,-100,0\n"), "") << "the range's ends are readings";
  EXPECT_THAT(errorOf(header + "1,0,0,0\n# a comment\n0.5,0,0,0\n"),
              HasSubstr("imu.csv:4: t 0.5 s is not after the sample before it (1 s): samples "
                        "out of order or given twice"));
  EXPECT_THAT(errorOf(header + "1,0,0,0\n1,0,0,0\n"), HasSubstr("imu.csv:3: t 1 s is not after"));
  // Control characters in an echoed field are escaped, a long one shortened.
  const std::string bad = errorOf(header + "1,\x1b[31m" + std::string(5000, 'x') + ",0,0\n");
  EXPECT_THAT(bad, HasSubstr("imu.csv:2: wx: '"));
  EXPECT_EQ(bad.find('\x1b'), std::string::npos);
  EXPECT_LT(bad.size(), 400u);
}

TEST(GyroCsv, ReadsAFileAndNamesOneItCannotRead) {
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("omnipose_gyro_test_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::ofstream(dir / "imu.csv") << "t,wx,wy,wz\n0.5,0.1,0.2,0.3\n";
  const GyroRecording r = readGyroCsv(dir / "imu.csv");
  ASSERT_EQ(r.samples.size(), 1u);
  EXPECT_EQ(r.samples[0].rate, Eigen::Vector3d(0.1, 0.2, 0.3));
  try {
    readGyroCsv(dir / "missing.csv");
    FAIL() << "a missing file was read";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr((dir / "missing.csv").string()));
  }
  std::ofstream(dir / "bad.csv") << "t,wx,wy,wz\n1,0,0\n";
  try {
    readGyroCsv(dir / "bad.csv");
    FAIL() << "a malformed file was read";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr((dir / "bad.csv").string() + ":2: 3 fields"));
  }
  fs::remove_all(dir);
}

TEST(GyroCsv, WhatIsWrittenReadsBackToTheNanosecondAndTenDigits) {
  const std::vector<GyroSample> samples = {{1700000000.123456789, Eigen::Vector3d(0.1234567891, -2e-7, 3.5)},
                                           {1700000000.128456789, Eigen::Vector3d(-1e-12, 0.0, -12.25)}};
  const GyroRecording r = parseGyroCsv(formatGyroCsv(samples), "written.csv");
  ASSERT_EQ(r.samples.size(), 2u);
  for (std::size_t i = 0; i < samples.size(); ++i) {
    EXPECT_NEAR(r.samples[i].t, samples[i].t, 1e-9);
    for (int axis = 0; axis < 3; ++axis)
      EXPECT_NEAR(r.samples[i].rate[axis], samples[i].rate[axis], 1e-9 * std::abs(samples[i].rate[axis]) + 1e-300);
  }
  EXPECT_NEAR(r.median_interval_s, 0.005, 1e-6);
  namespace fs = std::filesystem;
  const fs::path dir = fs::temp_directory_path() / ("omnipose_gyro_write_" + std::to_string(::getpid()));
  fs::create_directories(dir);
  writeGyroCsv(dir / "imu.csv", samples);
  EXPECT_EQ(readGyroCsv(dir / "imu.csv").samples.size(), 2u);
  try {
    writeGyroCsv(dir / "no" / "such" / "imu.csv", samples);
    ADD_FAILURE() << "wrote into a missing directory";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr((dir / "no" / "such" / "imu.csv").string()));
  }
  fs::remove_all(dir);
}

TEST(GyroCsv, ARecordingIsMadeOfSamplesInOrderOnly) {
  const Eigen::Vector3d still = Eigen::Vector3d::Zero();
  EXPECT_THROW(gyroRecordingOf({}), std::invalid_argument);
  EXPECT_THROW(gyroRecordingOf({{1.0, still}, {1.0, still}}), std::invalid_argument);
  EXPECT_THROW(gyroRecordingOf({{1.0, still}, {0.5, still}}), std::invalid_argument);
  const GyroRecording r = gyroRecordingOf({{0.0, still}, {0.01, still}, {0.02, still}, {0.2, still}});
  EXPECT_NEAR(r.median_interval_s, 0.01, 1e-15);
  EXPECT_EQ(r.gaps, 1);
  EXPECT_NEAR(r.longest_gap_s, 0.18, 1e-15);
}

}  // namespace
}  // namespace omnipose
