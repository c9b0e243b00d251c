// The map's pose graph solve (src/map/pose_graph.hpp), the work a loop closure adds to its
// frame: a full memory of N places driven round a square again and again (an odometry edge
// between consecutive places, a loop edge from every place of the second lap on back to the
// place of the first lap it passes), solved from the odometry's drifted chain with the
// default five rotation iterations. Reports; never gates CI.
// Run: build/bin/omnipose-bench-map
#include <benchmark/benchmark.h>

#include <cmath>
#include <numbers>

#include "bench_stats.hpp"
#include "map/pose_graph.hpp"
#include "planar_pose.hpp"

namespace {

using omnipose::map::PoseGraph;

/// The i-th place of laps of a unit square, 24 places a lap, heading along the path.
Eigen::Isometry3d place(int i) {
  constexpr int kPerLap = 24;
  const double s = 4.0 * static_cast<double>(i % kPerLap) / kPerLap;
  const int side = static_cast<int>(s);
  const double f = s - side;
  const double yaw = side * std::numbers::pi / 2;
  const double x = side == 0 ? f : side == 1 ? 1.0 : side == 2 ? 1.0 - f : 0.0;
  const double y = side == 0 ? 0.0 : side == 1 ? f : side == 2 ? 1.0 : 1.0 - f;
  return omnipose::testing::planarPose(x, y, yaw);
}

void BM_PoseGraphSolve(benchmark::State& state) {
  const int n = static_cast<int>(state.range(0));
  constexpr int kPerLap = 24;
  PoseGraph graph(n, 4 * n);
  Eigen::Isometry3d chain = place(0);
  graph.addNode(chain);
  for (int i = 1; i < n; ++i) {
    PoseGraph::Edge e;
    e.from = i - 1;
    e.to = i;
    e.relative = place(i - 1).inverse() * place(i) * omnipose::testing::planarPose(0, 0, 0.2 * std::numbers::pi / 180);
    e.rotation_sigma = 1e-3;
    e.position_sigma = 0.01;
    chain = chain * e.relative;
    graph.addNode(chain);
    graph.addEdge(e);
  }
  int loops = 0;
  for (int i = kPerLap; i < n; ++i) {
    PoseGraph::Edge e;
    e.from = i;
    e.to = i % kPerLap;
    e.relative = place(i).inverse() * place(i % kPerLap);
    e.rotation_sigma = 1e-3;
    e.position_sigma = 0.01;
    e.loop = true;
    loops += graph.addEdge(e) ? 1 : 0;
  }
  for (auto _ : state) {
    graph.solve();
    benchmark::DoNotOptimize(graph.pose(n - 1).translation().data());
  }
  state.counters["nodes"] = graph.nodeCount();
  state.counters["edges"] = graph.edgeCount();
  state.counters["loop_edges"] = loops;
}
BENCHMARK(BM_PoseGraphSolve)
    ->Arg(32)
    ->Arg(64)
    ->Arg(128)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(5)
    ->ComputeStatistics("min", omnipose::bench::minOf)
    ->ReportAggregatesOnly(true);

}  // namespace

BENCHMARK_MAIN();
