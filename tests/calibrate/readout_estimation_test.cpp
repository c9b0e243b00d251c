// The rolling-shutter readout measured from frames of a turning camera (readout_estimation.hpp)
// against renders whose rows the exact renderer drew at their own capture times.
#include "omnipose/calibrate/readout_estimation.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <sstream>
#include <vector>

#include "omnipose/synth/synth.hpp"

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
  EXPECT_NE(e.summary.find("cannot"), std::string::npos) << e.summary;
}

TEST(ReadoutEstimation, TooFewFramesAndBadOptionsAreNamed) {
  std::vector<cv::Mat> images(5, cv::Mat(720, 720, CV_8UC1, cv::Scalar(100)));
  std::vector<double> times = {0, 0.033, 0.067, 0.1, 0.133};
  const ReadoutEstimate e = estimateReadout(Calibration{}, images, times);
  EXPECT_FALSE(e.found);
  EXPECT_NE(e.summary.find("5 frames"), std::string::npos) << e.summary;
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
    EXPECT_NE(what.find("max_s"), std::string::npos) << what;
    EXPECT_NE(what.find("fine_step_s"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace omnipose::calibrate
