#include "omnipose/so3.hpp"

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>

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

double tiltAngle(const Eigen::Matrix3d& R) { return std::acos(std::clamp(R(2, 2), -1.0, 1.0)); }

Eigen::Matrix3d skew(const Eigen::Vector3d& v) {
  Eigen::Matrix3d K;
  K << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return K;
}

Eigen::Matrix3d rightJacobian(const Eigen::Vector3d& phi) {
  const double angle = phi.norm();
  const double a2 = angle * angle;
  // (1 - cos a) / a^2 and (a - sin a) / a^3, by their series where the quotients cancel.
  const bool small = angle < 1e-4;
  const double c1 = small ? 0.5 - a2 / 24.0 : (1.0 - std::cos(angle)) / a2;
  const double c2 = small ? 1.0 / 6.0 - a2 / 120.0 : (angle - std::sin(angle)) / (a2 * angle);
  const Eigen::Matrix3d K = skew(phi);
  return Eigen::Matrix3d::Identity() - c1 * K + c2 * K * K;
}

}  // namespace omnipose
