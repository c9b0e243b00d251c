#pragma once
// Shared helpers for tests that render frame pairs with the exact renderer.

#include <filesystem>
#include <string>

#include "omnipose/synth.hpp"
#include "omnipose/trajectory.hpp"

namespace omnipose::testing {

/// The bundled indoor photo (tests/data/equirect, MIT-licensed).
inline std::filesystem::path indoorPhoto() {
  return std::filesystem::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg";
}

/// The relative pose [exp(omega) | t] as a TUM-style camera pose (frame 0 at identity).
inline Eigen::Isometry3d relativePose(const Eigen::Vector3d& omega, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationFromVector(omega);
  T.translation() = t;
  return T;
}

}  // namespace omnipose::testing
