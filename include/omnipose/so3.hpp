#pragma once
/// \file so3.hpp
/// The rotation group SO(3) in rotation-vector form, as the motion model uses it
/// (DESIGN.md sections 2 and 3): omega = axis * angle (radians), R = exp([omega]x).

#include <Eigen/Core>
#include <Eigen/Geometry>

namespace omnipose {

/// Rotation vector (axis * angle, radians) of a rotation matrix: log(R), |result| in [0, pi].
/// Example: rotationVector(rotationFromVector({0, 0, 0.05})) = (0, 0, 0.05), a yaw of 0.05 rad.
Eigen::Vector3d rotationVector(const Eigen::Matrix3d& R);
/// Rotation matrix of a rotation vector: exp([omega]x) (Rodrigues); the identity for
/// |omega| < 1e-15.
Eigen::Matrix3d rotationFromVector(const Eigen::Vector3d& omega);
/// The angle (radians, in [0, pi]) by which R turns the z axis: between the z axes of two
/// cameras whose relative rotation is R, their tilt. Yaw alone leaves it 0 (to within 2e-8:
/// it is acos(R(2, 2))).
double tiltAngle(const Eigen::Matrix3d& R);
/// The cross-product matrix [v]x: skew(v) * w = v.cross(w).
Eigen::Matrix3d skew(const Eigen::Vector3d& v);
/// Right Jacobian of the exponential map: for a rotation vector phi(t),
/// exp([phi]x)^T d/dt exp([phi]x) = [rightJacobian(phi) * dphi/dt]x, so a rotation
/// R(t) = R0 exp([phi(t)]x) turns at rightJacobian(phi) * dphi/dt rad/s about its own axes.
/// The identity at phi = 0; exact (a series near 0) for any |phi| < 2 pi.
Eigen::Matrix3d rightJacobian(const Eigen::Vector3d& phi);
/// The rigid transform of rotation `R` and translation `t`: x -> R x + t.
inline Eigen::Isometry3d isometry(const Eigen::Matrix3d& R, const Eigen::Vector3d& t) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = R;
  T.translation() = t;
  return T;
}

}  // namespace omnipose
