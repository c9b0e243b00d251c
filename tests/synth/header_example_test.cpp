// The code example of include/omnipose/synth/synth.hpp, compiled and run: CMake copies the
// example's lines into synth_header_example.inc (tests/synth/CMakeLists.txt), so the header
// cannot show code that does not build or does not do what it says.
#include <gtest/gtest.h>

#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <filesystem>
#include <numbers>
#include <string>
#include <vector>

#include "omnipose/io/dataset.hpp"
#include "omnipose/so3.hpp"
#include "omnipose/synth/synth.hpp"

namespace omnipose {
namespace {

void synthHeaderExample() {
#include "synth_header_example.inc"
}

/// Runs `body` with `directory` as the working directory, and restores the old one.
template <typename Body>
void inDirectory(const std::filesystem::path& directory, Body body) {
  const std::filesystem::path previous = std::filesystem::current_path();
  std::filesystem::current_path(directory);
  try {
    body();
  } catch (...) {
    std::filesystem::current_path(previous);
    throw;
  }
  std::filesystem::current_path(previous);
}

TEST(SynthHeaderExample, WritesAFiveFrameYawDataset) {
  const std::filesystem::path dir = std::filesystem::temp_directory_path() /
                                    ("omnipose_header_example_" + std::to_string(::getpid()));
  std::filesystem::remove_all(dir);
  std::filesystem::create_directories(dir);
  std::filesystem::copy_file(
      std::filesystem::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg",
      dir / "indoor.jpg");

  inDirectory(dir, synthHeaderExample);

  const Dataset dataset = Dataset::open(dir / "out");
  EXPECT_EQ(dataset.frames.size(), 5u);
  ASSERT_TRUE(dataset.groundtruth.has_value());
  const std::vector<StampedPose>& poses = *dataset.groundtruth;
  ASSERT_EQ(poses.size(), 5u);
  double yaw = 0.0;
  for (std::size_t k = 1; k < poses.size(); ++k) {
    const Eigen::Matrix3d step = poses[k - 1].pose.linear().transpose() * poses[k].pose.linear();
    const Eigen::Vector3d omega = rotationVector(step);
    EXPECT_NEAR(omega.head<2>().norm(), 0.0, 1e-9) << "step " << k << " is not a pure yaw";
    yaw += std::abs(omega.z());
  }
  EXPECT_GT(yaw, 4 * std::numbers::pi / 180.0 - 1e-9) << "the yaw preset steps 1..6 deg per frame";
  std::filesystem::remove_all(dir);
}

}  // namespace
}  // namespace omnipose
