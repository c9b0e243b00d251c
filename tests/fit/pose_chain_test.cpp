#include "omnipose/pose_chain.hpp"

#include <gtest/gtest.h>

#include "omnipose/io/trajectory.hpp"

namespace omnipose {
namespace {

TEST(PoseChain, ComposesRelativePosesAsInverseTprevTimesT) {
  PoseChain chain;
  chain.start(0.0);
  EXPECT_TRUE(chain.pose().isApprox(Eigen::Isometry3d::Identity()));
  const Eigen::Matrix3d R = rotationFromVector(Eigen::Vector3d(0, 0, 0.1));
  const Eigen::Vector3d t(1, 0, 0);
  chain.append(1.0, R, t);
  chain.append(2.0, R, t);
  // T2 = [R t] [R t]: second step goes along the rotated x axis.
  const Eigen::Vector3d expected = t + R * t;
  EXPECT_TRUE(chain.pose().translation().isApprox(expected, 1e-12));
  EXPECT_NEAR(rotationVector(chain.pose().rotation()).z(), 0.2, 1e-12);
  EXPECT_EQ(chain.segment(), 0);
  EXPECT_EQ(chain.frames(), 3);
}

TEST(PoseChain, AGapStartsANewSegmentAndHoldsThePose) {
  PoseChain chain;
  chain.start(0.0);
  chain.append(1.0, Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.5, 0, 0));
  const Eigen::Isometry3d before = chain.pose();
  chain.start(5.0);
  EXPECT_EQ(chain.segment(), 1);
  EXPECT_TRUE(chain.pose().isApprox(before));
  chain.reset();
  EXPECT_EQ(chain.frames(), 0);
  EXPECT_TRUE(chain.pose().isApprox(Eigen::Isometry3d::Identity()));
}

TEST(RotationVector, RoundTripsAndHandlesZero) {
  const Eigen::Vector3d w(0.1, -0.2, 0.3);
  EXPECT_TRUE(rotationVector(rotationFromVector(w)).isApprox(w, 1e-12));
  EXPECT_LT(rotationVector(Eigen::Matrix3d::Identity()).norm(), 1e-15);
  EXPECT_TRUE(rotationFromVector(Eigen::Vector3d::Zero()).isIdentity());
}

}  // namespace
}  // namespace omnipose
