// Rotation vectors (include/omnipose/so3.hpp): the exponential and logarithm maps.
#include <gtest/gtest.h>

#include "omnipose/so3.hpp"

namespace omnipose {
namespace {

TEST(RotationVector, RoundTripsAndHandlesZero) {
  const Eigen::Vector3d w(0.1, -0.2, 0.3);
  EXPECT_TRUE(rotationVector(rotationFromVector(w)).isApprox(w, 1e-12));
  EXPECT_LT(rotationVector(Eigen::Matrix3d::Identity()).norm(), 1e-15);
  EXPECT_TRUE(rotationFromVector(Eigen::Vector3d::Zero()).isIdentity());
}

TEST(TiltAngle, IsTheAngleTheZAxisTurnsByAndIgnoresYaw) {
  // acos of R(2, 2): within sqrt(2 eps), 2e-8 rad, of 0 where the z axis does not turn.
  EXPECT_NEAR(tiltAngle(rotationFromVector(Eigen::Vector3d(0.0, 0.0, 2.5))), 0.0, 3e-8);
  EXPECT_NEAR(tiltAngle(rotationFromVector(Eigen::Vector3d(0.0, 0.07, 0.0))), 0.07, 1e-9);
  // A tilt of 0.05 about any horizontal axis, before or after a yaw: still 0.05.
  const Eigen::Matrix3d tilted = rotationFromVector(Eigen::Vector3d(0.03, -0.04, 0.0));
  const Eigen::Matrix3d yaw = rotationFromVector(Eigen::Vector3d(0.0, 0.0, 1.2));
  EXPECT_NEAR(tiltAngle(yaw * tilted), 0.05, 1e-9);
  EXPECT_NEAR(tiltAngle(tilted * yaw), 0.05, 1e-9);
  EXPECT_NEAR(tiltAngle(rotationFromVector(Eigen::Vector3d(3.1, 0.0, 0.0))), 3.1, 1e-7);
}

TEST(RightJacobian, IsTheBodyRateOfATimeVaryingRotationVector) {
  // phi(t) = phi0 + t * dphi: compare [Jr(phi0) dphi]x with R^T dR/dt by central
  // differences, for large, small and tiny angles (the series branch).
  for (const Eigen::Vector3d& phi0 : {Eigen::Vector3d(0.9, -1.7, 0.4), Eigen::Vector3d(0.02, 0.01, -0.03),
                                      Eigen::Vector3d(3e-6, -2e-6, 1e-6)}) {
    const Eigen::Vector3d dphi(0.3, 0.5, -0.7);
    const double h = 1e-6;
    const Eigen::Matrix3d dR =
        (rotationFromVector(phi0 + h * dphi) - rotationFromVector(phi0 - h * dphi)) / (2 * h);
    const Eigen::Matrix3d body = rotationFromVector(phi0).transpose() * dR;
    const Eigen::Vector3d rate(body(2, 1), body(0, 2), body(1, 0));
    EXPECT_LT((rightJacobian(phi0) * dphi - rate).norm(), 1e-8) << phi0.transpose();
  }
  EXPECT_TRUE(rightJacobian(Eigen::Vector3d::Zero()).isIdentity());
}

}  // namespace
}  // namespace omnipose
