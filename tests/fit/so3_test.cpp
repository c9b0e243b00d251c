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
