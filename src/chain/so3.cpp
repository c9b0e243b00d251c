#include "omnipose/so3.hpp"

#include <Eigen/Geometry>

namespace omnipose {

Eigen::Vector3d rotationVector(const Eigen::Matrix3d& R) {
  const Eigen::AngleAxisd aa(R);
  return aa.axis() * aa.angle();
}

Eigen::Matrix3d rotationFromVector(const Eigen::Vector3d& omega) {
  const double angle = omega.norm();
  if (angle < 1e-15) return Eigen::Matrix3d::Identity();
  return Eigen::AngleAxisd(angle, omega / angle).toRotationMatrix();
}

}  // namespace omnipose
