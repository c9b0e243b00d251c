// The rolling-shutter readout measured from frames of a turning camera (readout_estimation.hpp)
// against renders whose rows the exact renderer drew at their own capture times.
#include "omnipose/calibrate/readout_estimation.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <filesystem>
#include <sstream>
#include <vector>

#include "omnipose/synth/synth.hpp"
#include "test_files.hpp"

using ::testing::HasSubstr;

namespace omnipose::calibrate {
namespace {

/// A camera turning in place, speeding up and slowing down (yaw 0.5 to 3.5 deg per frame),
/// `frames` frames at 30 fps, rendered with `readout_s` from the bundled indoor photo.
void render(double readout_s, bool turning, int frames, std::vector<cv::Mat>& images,
            std::vector<double>& times) {
  std::ostringstream yaml;
  yaml << "frame_rate: 30\nsegments:\n";
  for (int k = 0; k + 1 < frames; ++k) {
    const double deg = turning ? 2.0 + 1.5 * std::sin(k * 0.6) : 0.0;
    yaml << "  - frames: 1\n";
    if (turning) yaml << "    rotation: {axis: z, step_deg: " << deg << ", sign: positive}\n";
  }
  const auto trajectory = synth::generateTrajectory(synth::MotionScript::parse(yaml.str()));
  const synth::Renderer renderer(
      synth::Scene::load(std::filesystem::path(OMNIPOSE_SOURCE_DIR) /
                             "tests/data/equirect/indoor_1024x512.jpg",
                         synth::SceneKind::kSphere),
      Calibration{}, {.supersample = 2});
  synth::DegradeOptions noise;
  noise.noise_sigma = 2.0;
  for (std::size_t k = 0; k < trajectory.size(); ++k) {
    const double t0 = trajectory[k].timestamp;
    images.push_back(synth::degrade(
        renderer.render([&](double t) { return synth::poseAtTime(trajectory, t0 + t); }, readout_s),
        noise, k));
    times.push_back(t0);
  }
}

/// A coarser search than the tool's (0.01 s, then 0.002 s): the test runs under the
/// sanitizers too.
ReadoutSearchOptions quickSearch() {
  ReadoutSearchOptions o;
  o.coarse_step_s = 0.01;
  o.fine_step_s = 0.002;
  return o;
}

TEST(ReadoutEstimation, FindsTheReadoutOfATurningCameraInEitherDirectionOrNone) {
  for (const double readout : {0.0267, -0.015, 0.0}) {
    std::vector<cv::Mat> images;
    std::vector<double> times;
    render(readout, true, 20, images, times);
    const ReadoutEstimate e = estimateReadout(Calibration{}, images, times, quickSearch());
    ::testing::Test::RecordProperty("estimate_of_" + std::to_string(readout) + "_s",
                                    std::to_string(e.readout_s));
    ASSERT_TRUE(e.found) << readout << ": " << e.summary;
    EXPECT_NEAR(e.readout_s, readout, 0.1 * std::abs(readout) + 0.001) << e.summary;
    EXPECT_GE(e.curve.size(), 11u);
  }
}

TEST(ReadoutEstimation, ACameraThatDoesNotTurnSaysItCannot) {
  std::vector<cv::Mat> images;
  std::vector<double> times;
  render(0.0267, false, 12, images, times);
  const ReadoutEstimate e = estimateReadout(Calibration{}, images, times, quickSearch());
  EXPECT_FALSE(e.found) << e.summary;
  EXPECT_THAT(e.summary, HasSubstr("cannot: the camera hardly turns"))
      << "not blamed on translation: " << e.summary;
  EXPECT_EQ(e.curve.size(), 1u) << "said after the first readout tried";
}

TEST(ReadoutEstimation, TooFewFramesAndBadOptionsAreNamed) {
  std::vector<cv::Mat> images(5, cv::Mat(720, 720, CV_8UC1, cv::Scalar(100)));
  std::vector<double> times = {0, 0.033, 0.067, 0.1, 0.133};
  const ReadoutEstimate e = estimateReadout(Calibration{}, images, times);
  EXPECT_FALSE(e.found);
  EXPECT_THAT(e.summary, HasSubstr("5 frames"));
  times.pop_back();
  EXPECT_THROW(estimateReadout(Calibration{}, images, times), std::invalid_argument);
  ReadoutSearchOptions bad;
  bad.max_s = 0.5;
  bad.fine_step_s = 0.0;
  try {
    estimateReadout(Calibration{}, images, std::vector<double>(5, 0.0), bad);
    FAIL();
  } catch (const std::invalid_argument& error) {
    const std::string what = error.what();
    EXPECT_THAT(what, HasSubstr("max_s"));
    EXPECT_THAT(what, HasSubstr("fine_step_s"));
  }
}


/// Runs omnipose-calibrate with `args`; its exit code and peak RSS (kB) from wait4().
struct ToolRun {
  int exit_code = -1;
  long max_rss_kb = 0;
};
ToolRun runCalibrate(const std::vector<std::string>& args, const std::filesystem::path& log) {
  const std::string tool =
      (std::filesystem::path(OMNIPOSE_BINARY_DIR) / "bin" / "omnipose-calibrate").string();
  std::vector<char*> argv{const_cast<char*>(tool.c_str())};
  for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_addopen(&actions, 1, log.c_str(), O_WRONLY | O_CREAT | O_TRUNC, 0644);
  posix_spawn_file_actions_adddup2(&actions, 1, 2);
  pid_t pid = -1;
  ToolRun run;
  const int spawned = posix_spawn(&pid, tool.c_str(), &actions, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&actions);
  if (spawned != 0) return run;
  int status = 0;
  rusage usage{};
  wait4(pid, &status, 0, &usage);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  run.max_rss_kb = usage.ru_maxrss;
  return run;
}

TEST(ReadoutCli, DecodesAtMostMaxFramesSoItsMemoryDoesNotGrowWithTheRecording) {
  // One rendered frame, linked as every frame of a 60- and a 1500-frame recording: the
  // camera stands still, so the estimate stops after one replay (and says why).
  std::vector<cv::Mat> images;
  std::vector<double> times;
  render(0.0, false, 2, images, times);
  const auto root = std::filesystem::temp_directory_path() /
                    ("omnipose_readout_cli_" + std::to_string(::getpid()));
  std::filesystem::remove_all(root);
  const auto makeRecording = [&](const std::string& name, int frames) {
    const auto dir = root / name;
    std::filesystem::create_directories(dir / "frames");
    Calibration{}.save(dir / "calibration.yaml");
    cv::imwrite((root / "frame.png").string(), images[0]);
    std::ofstream stamps(dir / "timestamps.txt");
    for (int k = 0; k < frames; ++k) {
      char file[32];
      std::snprintf(file, sizeof file, "%06d.png", k);
      std::filesystem::create_hard_link(root / "frame.png", dir / "frames" / file);
      stamps << file << " " << k / 30.0 << "\n";
    }
    return dir;
  };
  const auto small = makeRecording("small", 60);
  const auto large = makeRecording("large", 1500);
  const ToolRun a = runCalibrate({"--readout-from", small.string(), "--max-frames", "60", "--out",
                                  (root / "a.yaml").string()},
                                 root / "a.log");
  const ToolRun b = runCalibrate({"--readout-from", large.string(), "--max-frames", "60", "--out",
                                  (root / "b.yaml").string()},
                                 root / "b.log");
  const std::string log_b = omnipose::testing::readText(root / "b.log");
  EXPECT_EQ(a.exit_code, 1) << omnipose::testing::readText(root / "a.log");
  EXPECT_EQ(b.exit_code, 1) << log_b;
  EXPECT_THAT(log_b, HasSubstr("using frames 720 to 779 of 1500"));
  EXPECT_THAT(log_b, HasSubstr("cannot: the camera hardly turns"));
  ::testing::Test::RecordProperty("max_rss_kb_60_of_60", std::to_string(a.max_rss_kb));
  ::testing::Test::RecordProperty("max_rss_kb_60_of_1500", std::to_string(b.max_rss_kb));
  ASSERT_GT(a.max_rss_kb, 0);
  EXPECT_LE(b.max_rss_kb, a.max_rss_kb * 11 / 10) << "60 frames of 1500 cost what 60 of 60 do";
  EXPECT_FALSE(std::filesystem::exists(root / "b.yaml"));
  std::filesystem::remove_all(root);
}

}  // namespace
}  // namespace omnipose::calibrate
