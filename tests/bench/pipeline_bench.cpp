// Whole-pipeline benchmark at the paper's setting (W 1100, H = L = 110, d = 20: 55
// windows): unwrap + iFMI + fit + refinement per frame, on rendered omni frames, with 1 and
// 2 worker threads (PipelineOptions::threads), and the ORB rotation baseline (--method
// orbrot, one core) on the same frames in the same run; at the end it prints the ratio of
// each pipeline setting to orbrot (best repetition of each). Reports; never gates CI.
// The FFT plans are made as the daemon makes them with its wisdom file (FFTW_PATIENT, once
// per run; the file is a temporary one, removed at the end). FFTW_PATIENT times candidate
// plans, so two runs can pick different plans and differ in speed: to compare two builds,
// give both the same file with --wisdom FILE (written by the first run, kept).
// The realistic path (BM_OdometryRealistic) runs what the daemon and the replay run,
// omnipose::Odometry, on a 16-frame yaw swing encoded as PNG in memory, in three ways: the
// decoded frames back to back (what the scene content costs), each frame decoded just before
// it is processed (what the decoder's evictions cost), and decoded and paced at one frame
// every 33 ms (what the caches and the sleeping workers cost after 26 ms idle). Its time is
// Odometry::process alone (manual time); the decode is a counter.
// Run: build/bin/omnipose-bench-pipeline [--wisdom FILE] [Google Benchmark flags]
#include <benchmark/benchmark.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <cmath>
#include <limits>
#include <map>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <thread>
#include <vector>

#include "bench_stats.hpp"
#include "omnipose/baselines/feature_motion_estimator.hpp"
#include "omnipose/image_decode.hpp"
#include "omnipose/io/trajectory.hpp"
#include "omnipose/odometry.hpp"
#include "omnipose/pipeline.hpp"
#include "omnipose/synth/synth.hpp"

namespace {

using omnipose::Calibration;
using omnipose::Pipeline;
using omnipose::PipelineOptions;

/// The renderer of the bundled indoor photo (sphere scene, default calibration).
const omnipose::synth::Renderer& indoorRenderer() {
  static const omnipose::synth::Renderer renderer(
      omnipose::synth::Scene::load(
          std::filesystem::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg",
          omnipose::synth::SceneKind::kSphere),
      Calibration{});
  return renderer;
}

/// Two rendered omni frames 3 degrees of roll+yaw apart (the bundled indoor photo).
const std::array<cv::Mat, 2>& frames() {
  static const std::array<cv::Mat, 2> f = [] {
    const omnipose::synth::Renderer& renderer = indoorRenderer();
    Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
    T.linear() = omnipose::rotationFromVector(Eigen::Vector3d(0.03, 0.0, 0.04));
    std::array<cv::Mat, 2> out;
    renderer.render(Eigen::Isometry3d::Identity()).convertTo(out[0], CV_8U);
    renderer.render(T).convertTo(out[1], CV_8U);
    return out;
  }();
  return f;
}

/// A 16-frame yaw swing (0 to 16 deg and back, 2 deg a frame, with 1 deg of roll riding on
/// it), so the sequence repeats without a jump; each frame PNG-encoded as omnipose-synth
/// writes recordings (compression 3).
constexpr int kSwingFrames = 16;
const std::vector<std::vector<std::uint8_t>>& encodedSwing() {
  static const std::vector<std::vector<std::uint8_t>> encoded = [] {
    const omnipose::synth::Renderer& renderer = indoorRenderer();
    constexpr double kDeg = std::numbers::pi / 180.0;
    std::vector<std::vector<std::uint8_t>> out(kSwingFrames);
    for (int k = 0; k < kSwingFrames; ++k) {
      const int step = k <= kSwingFrames / 2 ? k : kSwingFrames - k;
      Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
      T.linear() = omnipose::rotationFromVector(
          Eigen::Vector3d(kDeg * std::sin(2.0 * std::numbers::pi * k / kSwingFrames), 0.0,
                          2.0 * kDeg * step));
      cv::Mat frame;
      renderer.render(T).convertTo(frame, CV_8U);
      cv::imencode(".png", frame, out[k], {cv::IMWRITE_PNG_COMPRESSION, 3});
    }
    return out;
  }();
  return encoded;
}

/// Best (smallest) seconds per frame of every benchmark setting over its repetitions.
std::map<std::string, double>& best() {
  static std::map<std::string, double> b;
  return b;
}

void record(const std::string& key, double seconds_per_frame) {
  auto [it, inserted] = best().emplace(key, seconds_per_frame);
  if (!inserted) it->second = std::min(it->second, seconds_per_frame);
}

using Clock = std::chrono::steady_clock;

/// The run's FFTW wisdom file (PipelineOptions::fftw_wisdom): --wisdom FILE, else a
/// temporary one that main() removes.
std::filesystem::path& wisdomFile() {
  static std::filesystem::path path;
  return path;
}
bool temporary_wisdom = true;

/// Takes `--wisdom FILE` (or --wisdom=FILE) out of argv, before Google Benchmark parses it.
void takeWisdomFlag(int& argc, char** argv) {
  int kept = 1;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "--wisdom" && i + 1 < argc) {
      wisdomFile() = argv[++i];
      temporary_wisdom = false;
    } else if (arg.starts_with("--wisdom=")) {
      wisdomFile() = arg.substr(9);
      temporary_wisdom = false;
    } else {
      argv[kept++] = argv[i];
    }
  }
  argc = kept;
  if (temporary_wisdom)
    wisdomFile() = std::filesystem::temp_directory_path() /
                   ("omnipose-bench-pipeline-wisdom-" + std::to_string(::getpid()) + ".txt");
}

void BM_PipelineFrame(benchmark::State& state) {
  cv::setNumThreads(1);  // OpenCV itself on one core; the pipeline's own pool only
  PipelineOptions options;
  options.refine_iterations = static_cast<int>(state.range(0));
  options.threads = static_cast<int>(state.range(1));
  options.fftw_wisdom = wisdomFile().string();
  Pipeline pipeline(Calibration{}, options);
  const auto& f = frames();
  (void)pipeline.process(f[0]);
  std::size_t i = 1;
  omnipose::StageTiming sum;
  const auto start = Clock::now();
  for (auto _ : state) {
    auto m = pipeline.process(f[i++ % 2]);
    benchmark::DoNotOptimize(m);
    sum.unwrap += m->timing.unwrap;
    sum.registration += m->timing.registration;
    sum.fit += m->timing.fit;
    sum.refine += m->timing.refine;
  }
  const double n = static_cast<double>(state.iterations());
  record("ifmi refine_iterations=" + std::to_string(options.refine_iterations) +
             " threads=" + std::to_string(options.threads),
         std::chrono::duration<double>(Clock::now() - start).count() / n);
  state.counters["unwrap_ms"] = 1e3 * sum.unwrap / n;
  state.counters["registration_ms"] = 1e3 * sum.registration / n;
  state.counters["fit_ms"] = 1e3 * sum.fit / n;
  state.counters["refine_ms"] = 1e3 * sum.refine / n;
  state.counters["windows"] = static_cast<double>(pipeline.lastWindows().size());
}

using omnipose::bench::minOf;

BENCHMARK(BM_PipelineFrame)
    ->ArgNames({"refine_iterations", "threads"})
    ->Args({1, 1})
    ->Args({1, 2})
    ->Args({0, 1})
    ->Args({0, 2})
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true)
    ->ComputeStatistics("min", minOf);

/// How BM_OdometryRealistic feeds its frames.
enum class Feed : int {
  kInMemory = 0,  ///< decoded once before the loop, back to back
  kDecoded = 1,   ///< each decoded just before it is processed, back to back
  kPaced = 2,     ///< each decoded just before it is processed, one every 33 ms
};

void BM_OdometryRealistic(benchmark::State& state) {
  cv::setNumThreads(1);
  const auto feed = static_cast<Feed>(state.range(0));
  omnipose::OdometryOptions options;  // the daemon's defaults, except:
  options.pipeline.threads = static_cast<int>(state.range(1));
  options.pipeline.fftw_wisdom = wisdomFile().string();
  omnipose::Odometry odometry(Calibration{}, options);
  const auto& encoded = encodedSwing();
  omnipose::ImageLimits limits;
  std::vector<cv::Mat> decoded(kSwingFrames);
  for (int k = 0; k < kSwingFrames; ++k) {
    if (!omnipose::decodeImage(encoded[k], omnipose::ImageColour::kGrey, limits, "swing frame",
                               decoded[k])) {
      state.SkipWithError("cannot decode a swing frame");
      return;
    }
    limits.exact_size = decoded[k].size();  // the frame size a recording declares
  }
  const auto period = std::chrono::microseconds(feed == Feed::kPaced ? 33333 : 0);
  cv::Mat frame;  // reused, as the daemon's file source reuses its buffer
  std::int64_t sequence = 0;
  (void)odometry.process(decoded[0], {0.0, sequence++});
  double decode_seconds = 0.0, process_seconds = 0.0;
  auto next = Clock::now();
  for (auto _ : state) {
    const int k = static_cast<int>(sequence % kSwingFrames);
    if (feed == Feed::kPaced) std::this_thread::sleep_until(next += period);
    const cv::Mat* input = &decoded[k];
    if (feed != Feed::kInMemory) {
      const auto t0 = Clock::now();
      if (!omnipose::decodeImage(encoded[k], omnipose::ImageColour::kGrey, limits, "swing frame",
                                 frame)) {
        state.SkipWithError("cannot decode a swing frame");
        return;
      }
      decode_seconds += std::chrono::duration<double>(Clock::now() - t0).count();
      input = &frame;
    }
    const auto t0 = Clock::now();
    auto r = odometry.process(*input, {static_cast<double>(sequence) / 30.0, sequence});
    const double seconds = std::chrono::duration<double>(Clock::now() - t0).count();
    benchmark::DoNotOptimize(r);
    if (!r || r->state != omnipose::TrackState::kTracked) {
      state.SkipWithError("the swing was not tracked");
      return;
    }
    ++sequence;
    process_seconds += seconds;
    state.SetIterationTime(seconds);
  }
  const double n = static_cast<double>(state.iterations());
  static constexpr const char* kFeedName[] = {"in memory", "decoded", "decoded+paced 33ms"};
  record("odometry " + std::string(kFeedName[static_cast<int>(feed)]) +
             " threads=" + std::to_string(options.pipeline.threads),
         process_seconds / n);
  state.counters["decode_ms"] = 1e3 * decode_seconds / n;
}

BENCHMARK(BM_OdometryRealistic)
    ->ArgNames({"feed", "threads"})
    ->ArgsProduct({{0, 1, 2}, {1, 2}})
    ->Iterations(96)  // six swings; 3.2 s a repetition when paced
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true)
    ->ComputeStatistics("min", minOf);

/// The ORB 2-point rotation baseline (omnipose-replay --method orbrot), OpenCV on one core.
void BM_OrbRotFrame(benchmark::State& state) {
  cv::setNumThreads(1);
  omnipose::baselines::FeatureMotionEstimator orbrot(
      Calibration{}, *omnipose::baselines::FeatureMotionOptions::forMethod("orbrot"));
  const auto& f = frames();
  (void)orbrot.process(f[0]);
  std::size_t i = 1;
  const auto start = Clock::now();
  for (auto _ : state) {
    auto m = orbrot.process(f[i++ % 2]);
    benchmark::DoNotOptimize(m);
  }
  record("orbrot", std::chrono::duration<double>(Clock::now() - start).count() /
                       static_cast<double>(state.iterations()));
}
BENCHMARK(BM_OrbRotFrame)
    ->Unit(benchmark::kMillisecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true)
    ->ComputeStatistics("min", minOf);

/// The best repetition of each benchmark, in ms per frame, with its ratio to orbrot (the
/// microbenchmarks) or to the microbenchmark at its thread count (the Odometry runs).
void printSummary() {
  const auto orb = best().find("orbrot");
  std::printf("\nBest repetition, ms per frame, and ratio to orbrot measured in this run:\n");
  for (const auto& [key, seconds] : best()) {
    if (key.starts_with("odometry")) continue;
    if (orb != best().end() && key != "orbrot")
      std::printf("  %-36s %7.2f ms  = %.2f x orbrot (%.2f ms)\n", key.c_str(), 1e3 * seconds,
                  seconds / orb->second, 1e3 * orb->second);
    else
      std::printf("  %-36s %7.2f ms\n", key.c_str(), 1e3 * seconds);
  }
  std::printf("\nThe realistic path (Odometry on the swing), best repetition, and its ratio to the\n"
              "microbenchmark above (refine_iterations=1) at the same thread count:\n");
  for (const auto& [key, seconds] : best()) {
    if (!key.starts_with("odometry")) continue;
    const std::string threads = key.substr(key.rfind(' ') + 1);
    const auto micro = best().find("ifmi refine_iterations=1 " + threads);
    if (micro != best().end())
      std::printf("  %-36s %7.2f ms  = %.2f x the microbenchmark (%.2f ms)\n", key.c_str(),
                  1e3 * seconds, seconds / micro->second, 1e3 * micro->second);
    else
      std::printf("  %-36s %7.2f ms\n", key.c_str(), 1e3 * seconds);
  }
}

}  // namespace

int main(int argc, char** argv) {
  takeWisdomFlag(argc, argv);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  if (temporary_wisdom) std::filesystem::remove(wisdomFile());
  printSummary();
  return 0;
}
