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

}  // namespace
}  // namespace omnipose
