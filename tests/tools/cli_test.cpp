// Every program's command line (tools/common/cli.hpp, CLI11), run as a user runs it:
// --help and --version succeed (exit 0) and print the usage and the project's version;
// an unknown flag and a malformed value are usage errors (exit 2) that name the flag.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cctype>
#include <cstdio>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <sstream>
#include <string>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/gyro.hpp"
#include "omnipose/io/dataset.hpp"
#include "omnipose/io/gyro.hpp"
#include "omnipose/io/trajectory.hpp"
#include "omnipose/so3.hpp"
#include "omnipose_version.hpp"
#include "test_files.hpp"

using ::testing::HasSubstr;

namespace {

namespace fs = std::filesystem;

struct Outcome {
  int exit_code = -1;
  std::string out, err;
};

std::string quote(const std::string& s) {
  std::string q = "'";
  for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
  return q + "'";
}

/// Runs build/bin/PROGRAM ARGS... with stdin from /dev/null; exit code, stdout, stderr.
Outcome run(const std::string& program, const std::vector<std::string>& args) {
  const fs::path dir = fs::temp_directory_path() / ("omnipose-cli-test-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  std::string cmd = quote((fs::path(OMNIPOSE_BINARY_DIR) / "bin" / program).string());
  for (const auto& a : args) cmd += " " + quote(a);
  cmd += " < /dev/null > " + quote((dir / "out").string()) + " 2> " + quote((dir / "err").string());
  const int status = std::system(cmd.c_str());
  Outcome r;
  r.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = omnipose::testing::readText(dir / "out");
  r.err = omnipose::testing::readText(dir / "err");
  fs::remove_all(dir);
  return r;
}

std::vector<std::string> programs() {
  std::vector<std::string> list;
  std::stringstream in(OMNIPOSE_CLI_PROGRAMS);
  for (std::string p; std::getline(in, p, ',');) list.push_back(p);
  return list;
}

class ProgramCli : public ::testing::TestWithParam<std::string> {};

TEST_P(ProgramCli, HelpPrintsTheUsageAndExitsZero) {
  const std::string program = GetParam();
  for (const char* flag : {"--help", "-h"}) {
    SCOPED_TRACE(flag);
    const Outcome r = run(program, {flag});
    EXPECT_EQ(r.exit_code, 0) << r.err;
    EXPECT_EQ(r.out.rfind("usage: " + program, 0), 0u) << "help must start with the usage:\n" << r.out;
    EXPECT_THAT(r.out, HasSubstr("--version"));
    EXPECT_THAT(r.out, HasSubstr("--help"));
    EXPECT_EQ(r.err, "");
  }
}

TEST_P(ProgramCli, VersionPrintsTheProjectVersionAndExitsZero) {
  const std::string program = GetParam();
  const Outcome r = run(program, {"--version"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.out, program + " " + OMNIPOSE_VERSION + "\n");
  EXPECT_EQ(r.err, "");
}

TEST_P(ProgramCli, UnknownFlagIsAUsageErrorNamingTheFlag) {
  const std::string program = GetParam();
  const Outcome r = run(program, {"--no-such-flag"});
  EXPECT_EQ(r.exit_code, 2) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr("--no-such-flag"));
  EXPECT_EQ(r.err.rfind(program + ": ", 0), 0u) << "the message starts with the program:\n" << r.err;
  EXPECT_THAT(r.err, HasSubstr("--help")) << "a hint to --help:\n" << r.err;
  EXPECT_EQ(r.out, "");
}

TEST_P(ProgramCli, BadValueIsAUsageErrorNamingTheFlag) {
  // One malformed value per program (a number that is not one, a name not in the list, a
  // missing value), with the other arguments valid so that the value is the only mistake.
  const std::map<std::string, std::vector<std::string>> bad = {
      {"omniposed", {"--config"}},
      {"omnipose-replay", {"dataset", "--input", "donut"}},
      {"omnipose-synth", {"--texture", "t.jpg", "--out", "o", "--frames", "ten"}},
      {"omnipose-eval", {"gt.tum", "est.tum", "--tolerance", "abc"}},
      {"omnipose-calibrate", {"frames", "--out", "c.yaml", "--center", "12"}},
      {"omnipose-listen", {"--count", "-1"}},
      {"omnipose-plot-fit", {"dataset", "--out", "f.png", "--pair", "0"}},
      {"omnipose-plot-angles", {"gt.tum", "est.tum", "--out", "f.png", "--axis", "diagonal"}},
      {"omnipose-results", {"manifest.tsv", "--main"}},
      {"omnipose-bench-instructions", {"--threads", "many"}},
      {"omnipose-equirect", {"--omni", "o.png", "--calibration", "c.yaml", "--out", "t.png", "--width", "wide"}},
      {"omnipose-plot-uncertainty", {"--texture", "t.jpg", "--out", "f.png", "--pairs", "0"}},
  };
  const std::map<std::string, std::string> flag = {
      {"omniposed", "--config"},         {"omnipose-replay", "--input"},
      {"omnipose-synth", "--frames"},    {"omnipose-eval", "--tolerance"},
      {"omnipose-calibrate", "--center"}, {"omnipose-listen", "--count"},
      {"omnipose-plot-fit", "--pair"},   {"omnipose-plot-angles", "--axis"},
      {"omnipose-results", "--main"},    {"omnipose-bench-instructions", "--threads"},
      {"omnipose-equirect", "--width"},  {"omnipose-plot-uncertainty", "--pairs"},
  };
  const std::string program = GetParam();
  ASSERT_TRUE(bad.contains(program)) << "add a bad value for " << program;
  const Outcome r = run(program, bad.at(program));
  EXPECT_EQ(r.exit_code, 2) << r.out << r.err;
  EXPECT_THAT(r.err, HasSubstr(flag.at(program)));
  EXPECT_EQ(r.err.rfind(program + ": ", 0), 0u) << r.err;
}

INSTANTIATE_TEST_SUITE_P(Programs, ProgramCli, ::testing::ValuesIn(programs()),
                         [](const ::testing::TestParamInfo<std::string>& info) {
                           std::string name;
                           for (char c : info.param) name += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
                           return name;
                         });

// Semantic checks the programs keep after parsing are usage errors too (exit 2).
TEST(ProgramCliChecks, SemanticMistakesExitTwo) {
  struct Case {
    std::string program;
    std::vector<std::string> args;
    std::string needle;
  };
  const std::vector<Case> cases = {
      {"omnipose-synth", {"--out", "o"}, "--texture"},
      {"omnipose-plot-uncertainty",
       {"--texture", "a.jpg", "--texture", "b.jpg", "--label", "a", "--out", "f.png"}, "--label"},
      {"omnipose-synth", {"--texture", "t.jpg", "--out", "o", "--jpeg", "101"}, "--jpeg"},
      {"omnipose-synth", {"--texture", "t.jpg", "--out", "o", "--write-mask"}, "--write-mask"},
      {"omnipose-synth", {"--texture", "t.jpg", "--out", "o", "--scene", "cube"}, "--scene"},
      {"omnipose-synth", {"--texture", "t.jpg", "--out", "o", "--readout", "0.05"}, "--readout"},
      {"omnipose-synth", {"--texture", "t.jpg", "--out", "o", "--texture-width", "1023"}, "--texture-width"},
      {"omnipose-synth", {"--texture", "t.jpg", "--out", "o", "--texture-turn", "nan"}, "--texture-turn"},
      {"omnipose-synth", {"--texture", "t.jpg", "--out", "o", "--exposure-times", "0.01,-0.002"}, "--exposure-times:"},
      {"omnipose-synth", {"--texture", "t.jpg", "--out", "o", "--exposure-times", "0.01", "--exposure-time", "0.01"},
       "give one of them"},
      {"omnipose-synth", {"--texture", "t.jpg", "--out", "o", "--exposure-times", "0.01,0.05"}, "--exposure-times: 0.05"},
      {"omnipose-synth", {"--texture", "t.jpg", "--out", "o", "--gyro-noise", "1e-4"}, "--gyro-noise needs --gyro-rate"},
      {"omnipose-synth", {"--texture", "t.jpg", "--out", "o", "--gyro-rate", "0"}, "--gyro-rate:"},
      {"omnipose-synth", {"--texture", "t.jpg", "--out", "o", "--gyro-rate", "200", "--gyro-bias", "-1"}, "--gyro-bias:"},
      {"omnipose-synth", {"--texture", "t.jpg", "--out", "o", "--gyro-rate", "200", "--gyro-rotation", "1,0,0"}, "--gyro-rotation:"},
      {"omnipose-synth", {"--texture", "t.jpg", "--out", "o", "--gyro-rate", "200", "--gyro-rotation", "1,0,0.5,0"}, "--gyro-rotation:"},
      {"omnipose-equirect", {"--omni", "o.png", "--out", "t.png"}, "--calibration"},
      {"omnipose-equirect", {"--omni", "o.png", "--calibration", "c.yaml", "--out", "t.png", "--width", "101"}, "--width"},
      {"omnipose-calibrate", {"frames"}, "--out"},
      {"omnipose-calibrate", {"--out", "c.yaml"}, "FRAMES"},
      {"omnipose-calibrate", {"frames", "--out", "c.yaml", "--direction", "up"}, "--direction"},
      {"omnipose-calibrate", {"frames", "--out", "c.yaml", "--max-frames", "0"}, "--max-frames"},
      {"omnipose-calibrate", {"frames", "--out", "c.yaml", "--max-frames", "many"}, "--max-frames"},
      {"omnipose-calibrate", {"frames", "--out", "no/such/dir/c.yaml"}, "--out"},
      {"omnipose-calibrate", {"--checkerboard", "9x6", "frames", "--out", "c.yaml"}, "--square"},
      {"omnipose-calibrate", {"--imu-from", "d"}, "--out"},
      {"omnipose-calibrate", {"--imu-from", "d", "--readout-from", "d", "--out", "c.yaml"}, "not both"},
      {"omnipose-calibrate", {"--imu-from", "d", "frames", "--out", "c.yaml"}, "--imu-from takes no FRAMES"},
      {"omnipose-eval", {"gt.tum"}, "EST.tum"},
      {"omnipose-plot-angles", {"gt.tum", "est.tum", "--labels", "a,b", "--out", "f.png"}, "--labels"},
      {"omnipose-replay", {}, "DATASET"},
      {"omnipose-replay", {"a", "b"}, "b"},
      {"omniposed", {}, "--config"},
      {"omniposed", {"--bogus"}, "--bogus"},  // the unknown flag, not the missing --config
  };
  for (const Case& c : cases) {
    std::string line = c.program;
    for (const auto& a : c.args) line += " " + a;
    SCOPED_TRACE(line);
    const Outcome r = run(c.program, c.args);
    EXPECT_EQ(r.exit_code, 2) << r.out << r.err;
    EXPECT_THAT(r.err, HasSubstr(c.needle));
  }
}

// omnipose-synth --gyro-rate: imu.csv holds the rendered motion's gyro and calibration.yaml
// the gyro's mounting and clock, so that integrating the samples with that calibration gives
// back each frame pair's rotation of groundtruth.tum.
TEST(SynthCli, WritesTheGyroOfTheRenderedMotionAndItsCalibration) {
  const fs::path dir = fs::temp_directory_path() / ("omnipose-synth-gyro-" + std::to_string(::getpid()));
  const fs::path photo = fs::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg";
  // Between frames: the smooth interpolation through the script's poses, and the spline whose
  // poses at the frames (groundtruth.tum) are its own.
  for (const std::string between : {"smooth", "spline"}) {
    SCOPED_TRACE(between);
    fs::remove_all(dir);
    const Outcome r = run("omnipose-synth",
                          {"--texture", photo.string(), "--out", dir.string(), "--preset", "mixed", "--frames", "6",
                           "--output", "panorama", "--supersample", "1", "--readout", "0.02", "--gyro-rate", "1000",
                           "--gyro-noise", "0", "--gyro-bias", "0", "--gyro-time-offset", "-0.003",
                           "--gyro-rotation", "0,0.6,0,0.8", "--between-frames", between, "--quiet"});
    ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
    EXPECT_THAT(r.out, HasSubstr("gyro 1000 Hz in imu.csv"));
    const omnipose::Calibration calibration = omnipose::Calibration::load(dir / "calibration.yaml");
    ASSERT_TRUE(calibration.imu.has_value());
    EXPECT_DOUBLE_EQ(calibration.imu->time_offset_s, -0.003);
    EXPECT_TRUE(calibration.imu->rotation.isApprox(Eigen::Quaterniond(0, 0.6, 0, 0.8), 1e-15));
    EXPECT_FALSE(calibration.imu->gyro_noise_density.has_value()) << "no noise: no density";
    const omnipose::GyroRecording gyro = omnipose::readGyroCsv(dir / "imu.csv");
    EXPECT_NEAR(gyro.median_interval_s, 0.001, 1e-9);
    const auto truth = omnipose::readTum(dir / "groundtruth.tum");
    ASSERT_EQ(truth.size(), 6u);
    // The samples cover every row of every frame (the last frame's rows end 20 ms after it).
    EXPECT_LE(gyro.samples.front().t + calibration.imu->time_offset_s, truth.front().timestamp - 0.09);
    EXPECT_GE(gyro.samples.back().t + calibration.imu->time_offset_s, truth.back().timestamp + 0.02 + 0.09);
    for (std::size_t k = 0; k + 1 < truth.size(); ++k) {
      const auto R = omnipose::integrateGyro(gyro.samples, *calibration.imu, Eigen::Vector3d::Zero(),
                                             truth[k].timestamp, truth[k + 1].timestamp, 0.01);
      ASSERT_TRUE(R.has_value()) << "pair " << k;
      const Eigen::Matrix3d pair = truth[k].pose.linear().transpose() * truth[k + 1].pose.linear();
      EXPECT_LT(omnipose::rotationVector(pair.transpose() * *R).norm(), 2e-5) << "pair " << k;
    }
  }
  fs::remove_all(dir);
}

// omnipose-synth --exposure-times: each frame exposed for its own time, which timestamps.txt
// records beside its stamp and the dataset reader gives back; the calibration states none.
TEST(SynthCli, WritesEachFramesExposureBesideItsTimestamp) {
  const fs::path dir = fs::temp_directory_path() / ("omnipose-synth-ae-" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const fs::path photo = fs::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg";
  const Outcome r = run("omnipose-synth",
                        {"--texture", photo.string(), "--out", dir.string(), "--preset", "mixed", "--frames", "5",
                         "--output", "panorama", "--supersample", "1", "--exposure-times", "0.004,0.016",
                         "--exposure-samples", "2", "--quiet"});
  ASSERT_EQ(r.exit_code, 0) << r.out << r.err;
  EXPECT_THAT(r.out, HasSubstr("exposures 2 cycled up to 0.016 s"));
  const omnipose::Dataset d = omnipose::Dataset::open(dir);
  ASSERT_EQ(d.frames.size(), 5u);
  for (std::size_t k = 0; k < d.frames.size(); ++k)
    EXPECT_DOUBLE_EQ(d.frames[k].exposure_s, k % 2 == 0 ? 0.004 : 0.016) << "frame " << k;
  EXPECT_EQ(d.calibration.sensor.exposure_s, 0.0);
  fs::remove_all(dir);
}

TEST(EquirectCli, WritesTheTextureOfARealMirrorImage) {
  const fs::path dir = fs::temp_directory_path() / ("omnipose-equirect-test-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path data = fs::path(OMNIPOSE_SOURCE_DIR) / "tests/data/catadioptric";
  {
    std::ofstream yaml(dir / "mirror.yaml");
    yaml << "omni:\n  model: ocamcalib\n  ocamcalib_file: " << (data / "mirror_office_ocamcalib.txt").string()
         << "\n  azimuth_zero_deg: 0.0\n  azimuth_direction: ccw\n"
            "panorama: {width: 1100, height: 110, horizon_row: 54.5, forward_column: 0.0}\n";
  }
  const Outcome ok = run("omnipose-equirect", {"--omni", (data / "mirror_office_1920x1080.jpg").string(),
                                               "--calibration", (dir / "mirror.yaml").string(),
                                               "--out", (dir / "office.png").string(), "--width", "512"});
  EXPECT_EQ(ok.exit_code, 0) << ok.out << ok.err;
  EXPECT_THAT(ok.out, HasSubstr("512 x 256"));
  EXPECT_THAT(ok.out, HasSubstr("elevations -40.5..27.1 deg"));
  EXPECT_GT(fs::file_size(dir / "office.png"), 10000u);

  const fs::path other = fs::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg";
  const Outcome bad = run("omnipose-equirect", {"--omni", other.string(), "--calibration",
                                                (dir / "mirror.yaml").string(), "--out",
                                                (dir / "bad.png").string()});
  EXPECT_EQ(bad.exit_code, 1) << bad.out << bad.err;
  EXPECT_THAT(bad.err, HasSubstr("indoor_1024x512.jpg"));
  EXPECT_FALSE(fs::exists(dir / "bad.png"));
  fs::remove_all(dir);
}

/// The numbers of a whitespace-separated list ("1.24 1.09 0.96").
std::vector<double> numbers(const std::string& text) {
  std::vector<double> out;
  std::istringstream in(text);
  for (double x; in >> x;) out.push_back(x);
  return out;
}

// omnipose-plot-uncertainty on renders of the indoor photo through the linear lens: the
// predicted standard deviations of the windows span more than a factor of 3 between the
// first and the last bin, and every bin's error follows its prediction (robust ratio within
// [0.6, 1.6]; the RMS ratio of every bin but the last, where the few peaks that jump go, too),
// and the windows' mean shift weighted by their inverse variances has much less noise than
// their plain mean (0.0030 against 0.0078 px in du). A missing texture is an error naming it (exit 1), nothing written.
TEST(PlotUncertaintyCli, PredictedSpreadFollowsTheErrorsOnRenders) {
  const fs::path dir = fs::temp_directory_path() / ("omnipose-uncertainty-test-" + std::to_string(::getpid()));
  fs::create_directories(dir);
  const fs::path photo = fs::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg";
  const Outcome ok = run("omnipose-plot-uncertainty",
                         {"--texture", photo.string(), "--pairs", "6", "--draws", "3", "--bins", "4",
                          "--supersample", "1", "--out", (dir / "u.png").string(), "--table",
                          (dir / "u.md").string()});
  ASSERT_EQ(ok.exit_code, 0) << ok.out << ok.err;
  EXPECT_GT(fs::file_size(dir / "u.png"), 10000u);
  std::ifstream table(dir / "u.md");
  int rows = 0;
  for (std::string line; std::getline(table, line);) {
    if (line.rfind("| indoor_1024x512 |", 0) != 0) continue;
    SCOPED_TRACE(line);
    ++rows;
    // | texture | windows | noise | axis | sd range | rms | robust | mean: plain / weighted |
    std::vector<std::string> cells;
    std::istringstream in(line);
    for (std::string cell; std::getline(in, cell, '|');) cells.push_back(cell);
    ASSERT_EQ(cells.size(), 9u);
    double sd_first = 0.0, sd_last = 0.0;
    ASSERT_EQ(std::sscanf(cells[5].c_str(), " %lf..%lf", &sd_first, &sd_last), 2);
    EXPECT_GT(sd_last, 3.0 * sd_first);
    const std::vector<double> rms = numbers(cells[6]), robust = numbers(cells[7]);
    ASSERT_EQ(rms.size(), 4u);
    ASSERT_EQ(robust.size(), 4u);
    for (std::size_t b = 0; b < 4; ++b) {
      EXPECT_GT(robust[b], 0.6) << "bin " << b + 1;
      EXPECT_LT(robust[b], 1.6) << "bin " << b + 1;
      if (b + 1 < 4) {
        EXPECT_GT(rms[b], 0.6) << "bin " << b + 1;
        EXPECT_LT(rms[b], 1.6) << "bin " << b + 1;
      }
    }
    double plain = 0.0, weighted = 0.0;
    ASSERT_EQ(std::sscanf(cells[8].c_str(), " %lf / %lf", &plain, &weighted), 2);
    EXPECT_LT(weighted, 0.6 * plain) << "weighting by the inverse variance averages noise away";
    EXPECT_GT(weighted, 0.0);
  }
  EXPECT_EQ(rows, 2) << "one row for du, one for dv";

  const Outcome missing = run("omnipose-plot-uncertainty",
                              {"--texture", (dir / "none.jpg").string(), "--out", (dir / "n.png").string()});
  EXPECT_EQ(missing.exit_code, 1) << missing.out << missing.err;
  EXPECT_THAT(missing.err, HasSubstr("none.jpg"));
  EXPECT_FALSE(fs::exists(dir / "n.png"));
  fs::remove_all(dir);
}

}  // namespace
