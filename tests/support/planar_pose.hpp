#pragma once
// A pose on the floor plane, as the map and loop-closure tests and the map benchmark drive.

#include <Eigen/Geometry>

#include "omnipose/so3.hpp"

namespace omnipose::testing {

/// The pose at (x, y, 0) turned `yaw` radians about z.
inline Eigen::Isometry3d planarPose(double x, double y, double yaw) {
  return isometry(rotationFromVector(Eigen::Vector3d(0.0, 0.0, yaw)), Eigen::Vector3d(x, y, 0.0));
}

}  // namespace omnipose::testing
