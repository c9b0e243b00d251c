#pragma once
// Poses the synth tests render from (shared by synth_test.cpp and synth_effects_test.cpp).

#include <Eigen/Geometry>

#include "omnipose/so3.hpp"

namespace omnipose::synth::test {

/// The rotation exp([omega]x) at the origin.
inline Eigen::Isometry3d rotation(const Eigen::Vector3d& omega) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationFromVector(omega);
  return T;
}

/// The translation t without rotation.
inline Eigen::Isometry3d translation(const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.translation() = t;
  return T;
}

}  // namespace omnipose::synth::test
