// omnipose-calibrate --propose-mask: on a rendered turn with a static mast, the
// proposed mask covers the mast and little else; frames without motion are refused.
#include "omnipose/calibrate/mask_proposal.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

#include "omnipose/io/trajectory.hpp"
#include "omnipose/synth/synth.hpp"
#include "test_figures.hpp"

using ::testing::HasSubstr;

namespace omnipose::calibrate {
namespace {

const std::filesystem::path kIndoor =
    std::filesystem::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg";

/// 8 frames of a yaw turn (3 deg per frame) with a 40-deg mast at image angle 30 deg.
std::vector<cv::Mat> turnWithMast(const Calibration& c, const synth::Occluder& mast, double step_rad) {
  const synth::Renderer renderer(synth::Scene::load(kIndoor, synth::SceneKind::kSphere), c, {synth::OutputKind::kOmni, 1});
  synth::DegradeOptions noise;
  noise.noise_sigma = 3.0;
  std::vector<cv::Mat> frames;
  for (int k = 0; k < 8; ++k) {
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = rotationFromVector(Eigen::Vector3d(0, 0, step_rad * k));
    cv::Mat image = renderer.render(T);
    mast.paint(image, c);
    frames.push_back(synth::degrade(image, noise, k));
  }
  return frames;
}

TEST(MaskProposal, CoversTheMastAndLittleElse) {
  if (!std::filesystem::exists(kIndoor)) GTEST_SKIP() << "missing " << kIndoor;
  const Calibration c;  // 720 x 720, ring 120..300
  const synth::Occluder mast{30.0, 40.0};
  const auto frames = turnWithMast(c, mast, 3.0 * M_PI / 180);
  const MaskProposal p = proposeMask(frames);
  ASSERT_EQ(p.mask.size(), frames.front().size());
  const cv::Mat truth = mast.mask(c, 0.0);     // 0 on the mast
  const cv::Mat wide = mast.mask(c, 4.0);      // 0 on the mast and 4 deg either side
  int on_mast = 0, on_mast_masked = 0, elsewhere = 0, elsewhere_masked = 0;
  for (int y = 0; y < truth.rows; ++y)
    for (int x = 0; x < truth.cols; ++x) {
      const double r = std::hypot(x - c.omni.center_x, y - c.omni.center_y);
      if (r < c.omni.radius_inner + 10 || r > c.omni.radius_outer - 10) continue;  // bezel edges
      const bool masked = p.mask.at<uchar>(y, x) == 0;
      if (truth.at<uchar>(y, x) == 0) {
        ++on_mast;
        on_mast_masked += masked;
      } else if (wide.at<uchar>(y, x) != 0) {
        ++elsewhere;
        elsewhere_masked += masked;
      }
    }
  const double recall = static_cast<double>(on_mast_masked) / on_mast;
  const double false_positive = static_cast<double>(elsewhere_masked) / elsewhere;
  testing::recordFigure("mast_covered_percent", 100 * recall, 1);
  testing::recordFigure("rest_of_ring_masked_percent", 100 * false_positive, 2);
  testing::recordFigure("patches_moved_percent", 100 * p.moving_fraction, 0);
  EXPECT_GT(recall, 0.95) << "fraction of the mast masked";
  EXPECT_LT(false_positive, 0.03) << "fraction of the rest of the ring masked";
}

TEST(MaskProposal, RefusesFramesWithoutMotion) {
  if (!std::filesystem::exists(kIndoor)) GTEST_SKIP() << "missing " << kIndoor;
  const Calibration c;
  const auto frames = turnWithMast(c, synth::Occluder{30.0, 40.0}, 0.0);
  try {
    proposeMask(frames);
    FAIL() << "expected a refusal";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("hardly moved"));
    EXPECT_THAT(e.what(), HasSubstr("record a short turn"));
  }
}

TEST(MaskProposal, NeedsThreeFramesOfOneSize) {
  std::vector<cv::Mat> two(2, cv::Mat(64, 64, CV_8UC1, cv::Scalar(9)));
  EXPECT_THROW(proposeMask(two), std::runtime_error);
  std::vector<cv::Mat> mixed = {cv::Mat(64, 64, CV_8UC1), cv::Mat(64, 64, CV_8UC1), cv::Mat(32, 64, CV_8UC1)};
  EXPECT_THROW(proposeMask(mixed), std::runtime_error);
}

}  // namespace
}  // namespace omnipose::calibrate
