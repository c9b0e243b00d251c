// The pose graph over places (src/map/pose_graph.hpp): a loop driven with a heading drift,
// closed by one exact edge, comes out with the drift spread over the loop and the closure
// met; removing a node keeps its neighbours joined; solving allocates nothing.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <vector>

#include "allocation_counter.hpp"
#include "map/pose_graph.hpp"
#include "planar_pose.hpp"
#include "omnipose/so3.hpp"

namespace omnipose::map {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

Eigen::Isometry3d pose(double yaw, double x, double y) { return testing::planarPose(x, y, yaw); }

double yawError(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
  return rotationVector(a.linear().transpose() * b.linear()).norm();
}

/// A square of side 1 driven counter-clockwise, `per_side` nodes a side, each odometry edge
/// turning `drift` rad more than the truth; the truth and the odometry's chain.
struct DriftedSquare {
  std::vector<Eigen::Isometry3d> truth, chain;
  std::vector<PoseGraph::Edge> odometry;
};

DriftedSquare driftedSquare(int per_side, double drift) {
  DriftedSquare s;
  for (int side = 0; side < 4; ++side) {
    for (int k = 0; k < per_side; ++k) {
      const double yaw = side * std::numbers::pi / 2;
      const Eigen::Vector3d start = side == 0   ? Eigen::Vector3d(0, 0, 0)
                                    : side == 1 ? Eigen::Vector3d(1, 0, 0)
                                    : side == 2 ? Eigen::Vector3d(1, 1, 0)
                                                : Eigen::Vector3d(0, 1, 0);
      const Eigen::Vector3d along = rotationFromVector(Eigen::Vector3d(0, 0, yaw)) * Eigen::Vector3d::UnitX();
      const Eigen::Vector3d p = start + along * (static_cast<double>(k) / per_side);
      s.truth.push_back(pose(yaw, p.x(), p.y()));
    }
  }
  s.chain.push_back(s.truth[0]);
  for (std::size_t i = 1; i < s.truth.size(); ++i) {
    PoseGraph::Edge e;
    e.from = static_cast<int>(i - 1);
    e.to = static_cast<int>(i);
    e.relative = s.truth[i - 1].inverse() * s.truth[i] * pose(drift, 0.0, 0.0);
    e.rotation_sigma = 1e-3;
    e.position_sigma = 0.01;
    s.odometry.push_back(e);
    s.chain.push_back(s.chain.back() * e.relative);
  }
  return s;
}

/// The loop edge from node `from` back to node 0, exact (the truth's), much surer than the
/// odometry's edges.
PoseGraph::Edge exactLoop(const DriftedSquare& s, int from) {
  PoseGraph::Edge loop;
  loop.from = from;
  loop.to = 0;
  loop.relative = s.truth[static_cast<std::size_t>(from)].inverse() * s.truth[0];
  loop.rotation_sigma = 1e-4;
  loop.position_sigma = 1e-3;
  loop.loop = true;
  return loop;
}

TEST(PoseGraph, AnExactLoopEdgeSpreadsTheDriftAndClosesTheLoop) {
  const DriftedSquare s = driftedSquare(5, 0.5 * kDeg);
  PoseGraph graph(32, 64);
  for (const auto& T : s.chain) ASSERT_GE(graph.addNode(T), 0);
  for (const auto& e : s.odometry) ASSERT_TRUE(graph.addEdge(e));
  const int last = static_cast<int>(s.truth.size()) - 1;
  const double drift_before = yawError(graph.pose(last), s.truth[last]);
  EXPECT_NEAR(drift_before, last * 0.5 * kDeg, 1e-9);

  const PoseGraph::Edge loop = exactLoop(s, last);
  ASSERT_TRUE(graph.addEdge(loop));
  graph.solve();

  EXPECT_TRUE(graph.pose(0).isApprox(s.chain[0])) << "node 0 holds the gauge";
  // The loop edge is met (it is 10 x tighter than an odometry edge), and each node's heading
  // error is what is left of the drift once spread: at most half of the uncorrected end's.
  const Eigen::Isometry3d closure = graph.pose(last).inverse() * graph.pose(0);
  EXPECT_LT(yawError(closure, loop.relative), 0.02 * drift_before);
  double worst = 0.0;
  for (int i = 0; i <= last; ++i) worst = std::max(worst, yawError(graph.pose(i), s.truth[i]));
  EXPECT_LT(worst, 0.3 * drift_before);
  // The positions follow: the end meets the start.
  EXPECT_LT((graph.pose(last).translation() - s.truth[last].translation()).norm(), 0.05);
  const double chain_gap = (s.chain[last].translation() - s.truth[last].translation()).norm();
  EXPECT_GT(chain_gap, 0.1) << "the drifted chain's end is off";
}

TEST(PoseGraph, ARemovedNodeLeavesItsNeighboursJoined) {
  const DriftedSquare s = driftedSquare(4, 0.0);
  PoseGraph graph(16, 32);
  for (const auto& T : s.chain) graph.addNode(T);
  for (const auto& e : s.odometry) graph.addEdge(e);
  const int edges = graph.edgeCount();
  graph.removeNode(5);
  EXPECT_FALSE(graph.alive(5));
  EXPECT_EQ(graph.nodeCount(), 15);
  EXPECT_EQ(graph.edgeCount(), edges - 1) << "4-5 and 5-6 became 4-6";
  // A yaw error on the far side, then an exact loop edge: the correction reaches across.
  const int last = 15;
  Eigen::Isometry3d moved = graph.pose(last) * pose(3 * kDeg, 0, 0);
  PoseGraph bumped(16, 32);
  for (int i = 0; i <= last; ++i) bumped.addNode(i == last ? moved : s.chain[static_cast<std::size_t>(i)]);
  for (const auto& e : s.odometry) bumped.addEdge(e);
  bumped.removeNode(5);
  ASSERT_TRUE(bumped.addEdge(exactLoop(s, last)));
  bumped.solve();
  for (int i = 0; i <= last; ++i) {
    if (i == 5) continue;
    EXPECT_LT(yawError(bumped.pose(i), s.truth[static_cast<std::size_t>(i)]), 1e-6) << i;
    EXPECT_LT((bumped.pose(i).translation() - s.truth[static_cast<std::size_t>(i)].translation()).norm(), 1e-6) << i;
  }
  graph.removeNode(0);
  EXPECT_TRUE(graph.alive(0)) << "node 0 holds the gauge: it is never removed";
}

TEST(PoseGraph, ALoopEdgeBetweenTheSameNodesReplacesTheOlderOne) {
  PoseGraph graph(4, 8);
  graph.addNode(Eigen::Isometry3d::Identity());
  graph.addNode(pose(0.1, 1, 0));
  PoseGraph::Edge loop;
  loop.from = 1;
  loop.to = 0;
  loop.relative = pose(-0.2, -1, 0);
  loop.loop = true;
  ASSERT_TRUE(graph.addEdge(loop));
  loop.from = 0;
  loop.to = 1;
  loop.relative = pose(0.05, 1, 0);
  ASSERT_TRUE(graph.addEdge(loop));
  EXPECT_EQ(graph.edgeCount(), 1);
  graph.solve();
  EXPECT_NEAR(yawError(graph.pose(1), pose(0.05, 1, 0)), 0.0, 1e-9) << "the newer measurement";
  loop.to = 0;
  EXPECT_FALSE(graph.addEdge(loop)) << "a node with itself";
  loop.to = 3;
  EXPECT_FALSE(graph.addEdge(loop)) << "an unknown node";
}

TEST(PoseGraph, UnreachedNodesKeepTheirPoses) {
  PoseGraph graph(4, 8);
  graph.addNode(Eigen::Isometry3d::Identity());
  graph.addNode(pose(0.1, 1, 0));
  graph.addNode(pose(0.3, 2, 0));
  PoseGraph::Edge e;
  e.from = 1;
  e.to = 2;
  e.relative = pose(0.0, 1, 0);
  ASSERT_TRUE(graph.addEdge(e));
  graph.solve();
  EXPECT_TRUE(graph.pose(1).isApprox(pose(0.1, 1, 0)));
  EXPECT_TRUE(graph.pose(2).isApprox(pose(0.3, 2, 0)));
}

TEST(PoseGraph, SolvingAllocatesNothing) {
  if (!testing::AllocationCounter::available())
    GTEST_SKIP() << "sanitizer build: the sanitizer owns malloc, allocations are not counted";
  const DriftedSquare s = driftedSquare(25, 0.1 * kDeg);
  PoseGraph graph(128, 512);
  testing::AllocationCounter counter;
  for (const auto& T : s.chain) graph.addNode(T);
  for (const auto& e : s.odometry) graph.addEdge(e);
  graph.addEdge(exactLoop(s, 99));
  graph.solve();
  graph.removeNode(50);
  graph.solve();
  EXPECT_EQ(counter.stop(), 0);
}

}  // namespace
}  // namespace omnipose::map
