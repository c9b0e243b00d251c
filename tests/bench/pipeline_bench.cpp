// Whole-pipeline benchmark at the paper's setting (W 1100, H = L = 110, d = 20: 55
// windows), one core: unwrap + iFMI + fit + refinement per frame, on rendered omni frames.
// Reports; never gates CI. Run: build/bin/omnipose-bench-pipeline
#include <benchmark/benchmark.h>

#include <filesystem>
#include <opencv2/core.hpp>

#include "omnipose/pipeline.hpp"
#include "omnipose/synth.hpp"
#include "omnipose/trajectory.hpp"

namespace {

using omnipose::Calibration;
using omnipose::Pipeline;
using omnipose::PipelineOptions;

/// Two rendered omni frames 3 degrees of roll+yaw apart (the bundled indoor photo).
const std::array<cv::Mat, 2>& frames() {
  static const std::array<cv::Mat, 2> f = [] {
    const auto photo =
        std::filesystem::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg";
    omnipose::synth::Renderer renderer(
        omnipose::synth::Scene::load(photo, omnipose::synth::SceneKind::kSphere), Calibration{});
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = omnipose::rotationFromVector(Eigen::Vector3d(0.03, 0.0, 0.04));
    std::array<cv::Mat, 2> out;
    renderer.render(Eigen::Isometry3d::Identity()).convertTo(out[0], CV_8U);
    renderer.render(T).convertTo(out[1], CV_8U);
    return out;
  }();
  return f;
}

void BM_PipelineFrame(benchmark::State& state) {
  cv::setNumThreads(1);  // one core, as on the robot's budget
  PipelineOptions options;
  options.refine_iterations = static_cast<int>(state.range(0));
  Pipeline pipeline(Calibration{}, options);
  const auto& f = frames();
  (void)pipeline.process(f[0]);
  std::size_t i = 1;
  omnipose::StageTiming sum;
  for (auto _ : state) {
    auto m = pipeline.process(f[i++ % 2]);
    benchmark::DoNotOptimize(m);
    sum.unwrap += m->timing.unwrap;
    sum.registration += m->timing.registration;
    sum.fit += m->timing.fit;
    sum.refine += m->timing.refine;
  }
  const double n = static_cast<double>(state.iterations());
  state.counters["unwrap_ms"] = 1e3 * sum.unwrap / n;
  state.counters["registration_ms"] = 1e3 * sum.registration / n;
  state.counters["fit_ms"] = 1e3 * sum.fit / n;
  state.counters["refine_ms"] = 1e3 * sum.refine / n;
  state.counters["windows"] = static_cast<double>(pipeline.lastWindows().size());
}
BENCHMARK(BM_PipelineFrame)
    ->ArgName("refine_iterations")
    ->Arg(0)
    ->Arg(1)
    ->Arg(2)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true)
    ->ComputeStatistics("min", [](const std::vector<double>& v) {
      return *std::min_element(v.begin(), v.end());
    });

}  // namespace

BENCHMARK_MAIN();
