// The registration's four FFTs, as FftPlan makes them (two batched 1-D FFTW plans through a
// scratch array; FFTW_MEASURE and FFTW_PATIENT) and as FFTW's own 2-D plan
// (fftwf_plan_dft_r2c_2d / c2r_2d, FFTW_MEASURE | FFTW_NO_BUFFERING), on the same arrays:
// the measurement behind src/runtime/fft_plan.hpp's choice. Reports; never gates CI.
// Run: build/bin/omnipose-bench-fft
#include <benchmark/benchmark.h>
#include <fftw3.h>

#include <cmath>
#include <cstddef>
#include <cstring>
#include <mutex>

#include "bench_stats.hpp"
#include "runtime/fft_plan.hpp"

namespace {

namespace runtime = omnipose::runtime;

/// The transforms of one window registration at the paper setting (L = 110).
enum Transform : int {
  kWindowR2c,       ///< r2c 112 x 112: the tapered window
  kTranslationC2r,  ///< c2r 108 x 108: the translation correlation surface
  kLogPolarR2c,     ///< r2c 96 x 64: the log-polar image
  kLogPolarC2r,     ///< c2r 96 x 64: the rotation/scale correlation surface
};

struct Shape {
  int rows, cols;
  bool forward;
};

Shape shapeOf(int t) {
  switch (t) {
    case kWindowR2c: return {112, 112, true};
    case kTranslationC2r: return {108, 108, false};
    case kLogPolarR2c: return {96, 64, true};
    default: return {96, 64, false};
  }
}

enum Method : int { kFftw2d, kTwoPassMeasure, kTwoPassPatient };

void BM_Fft(benchmark::State& state) {
  const Shape s = shapeOf(static_cast<int>(state.range(0)));
  const auto method = static_cast<Method>(state.range(1));
  const std::size_t bins = static_cast<std::size_t>(s.rows) * (s.cols / 2 + 1);
  runtime::FftwArray<float> real(static_cast<std::size_t>(s.rows) * s.cols);
  runtime::FftwArray<runtime::Complex> spectrum(bins);
  fftwf_plan plan2d = nullptr;
  runtime::FftPlan plan;
  if (method == kFftw2d) {
    std::lock_guard lock(runtime::fftwPlannerMutex());
    auto* z = reinterpret_cast<fftwf_complex*>(spectrum.data());
    const unsigned flags = FFTW_MEASURE | FFTW_NO_BUFFERING;
    plan2d = s.forward ? fftwf_plan_dft_r2c_2d(s.rows, s.cols, real.data(), z, flags)
                       : fftwf_plan_dft_c2r_2d(s.rows, s.cols, z, real.data(), flags);
  } else {
    const auto effort =
        method == kTwoPassPatient ? runtime::PlanEffort::kPatient : runtime::PlanEffort::kMeasure;
    plan = s.forward
               ? runtime::FftPlan::realToComplex(s.rows, s.cols, real.data(), spectrum.data(), effort)
               : runtime::FftPlan::complexToReal(s.rows, s.cols, spectrum.data(), real.data(), effort);
  }
  for (std::size_t i = 0; i < real.size(); ++i) real[i] = std::sin(0.37f * static_cast<float>(i));
  for (std::size_t i = 0; i < bins; ++i) {
    const float x = static_cast<float>(i);
    spectrum[i] = {std::cos(0.11f * x), std::sin(0.23f * x)};
  }
  // The 2-D c2r plan overwrites its input on every execute (FFTW's default for c2r, as in
  // the pipeline before FftPlan): it gets the same input again, outside the timing.
  const bool refresh = plan2d != nullptr && !s.forward;
  runtime::FftwArray<runtime::Complex> input(bins);
  std::memcpy(input.data(), spectrum.data(), bins * sizeof(runtime::Complex));
  for (auto _ : state) {
    if (refresh) {
      state.PauseTiming();
      std::memcpy(spectrum.data(), input.data(), bins * sizeof(runtime::Complex));
      state.ResumeTiming();
    }
    if (plan2d != nullptr)
      fftwf_execute(plan2d);
    else
      plan.execute();
    benchmark::ClobberMemory();
  }
  if (plan2d != nullptr) {
    std::lock_guard lock(runtime::fftwPlannerMutex());
    fftwf_destroy_plan(plan2d);
  }
}

// Arguments: transform (0 window r2c 112^2, 1 translation c2r 108^2, 2 log-polar r2c 96x64,
// 3 log-polar c2r 96x64), method (0 FFTW 2-D plan, 1 two passes FFTW_MEASURE, 2 two passes
// FFTW_PATIENT).
BENCHMARK(BM_Fft)
    ->ArgNames({"transform", "method"})
    ->ArgsProduct({{kWindowR2c, kTranslationC2r, kLogPolarR2c, kLogPolarC2r},
                   {kFftw2d, kTwoPassMeasure, kTwoPassPatient}})
    ->Unit(benchmark::kMicrosecond)
    ->Repetitions(5)
    ->ReportAggregatesOnly(true)
    ->ComputeStatistics("min", omnipose::bench::minOf);

}  // namespace

BENCHMARK_MAIN();
