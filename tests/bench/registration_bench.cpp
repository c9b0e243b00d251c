/// \file registration_bench.cpp
/// Time of one frame of sliding-window iFMI registration (measure + advance) at the paper's
/// setting (W = 1100, H = L = 110, d = 20: 55 windows) on a real-texture panorama pair.
/// Reports the time per frame and per window (counter "per_window", seconds).
///
/// The pair alternates between two frames A and B that differ by a sub-pixel shift and a
/// small in-window rotation/scale (as between two video frames), so every iteration does the
/// full work, including the de-rotation of the translation stage.

#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "omnipose/window_registration.hpp"
#include "registration/test_images.hpp"

namespace {

using omnipose::WindowMotion;
using omnipose::WindowRegistration;

/// The park photo as a 1100 x 110 grey panorama band about the horizon, or a synthetic
/// texture when the photo is missing (same cost: the FFT work does not depend on content).
cv::Mat panoramaBand(int width, int height) {
  if (const std::string path = omnipose::test::equirectPath(omnipose::test::kPark); !path.empty()) {
    const cv::Mat grey = cv::imread(path, cv::IMREAD_GRAYSCALE);
    if (!grey.empty()) {
      cv::Mat resized, band;
      cv::resize(grey, resized, cv::Size(width, width / 2), 0, 0, cv::INTER_AREA);
      resized.rowRange(width / 4 - height / 2, width / 4 - height / 2 + height).convertTo(band, CV_32F);
      return band;
    }
  }
  cv::Mat noise(height, width, CV_32F);
  cv::randn(noise, 128.0, 40.0);
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), 1.5);
  return noise;
}

/// `band` moved by (du, dv) pixels and rotated by `degrees` about its centre row.
cv::Mat moved(const cv::Mat& band, double du, double dv, double degrees) {
  cv::Mat m = cv::getRotationMatrix2D(cv::Point2f(0.5f * band.cols, 0.5f * (band.rows - 1)), degrees, 1.0);
  m.at<double>(0, 2) += du;
  m.at<double>(1, 2) += dv;
  cv::Mat out;
  cv::warpAffine(band, out, m, band.size(), cv::INTER_CUBIC, cv::BORDER_REFLECT);
  return out;
}

struct Frames {
  WindowRegistration::Options options;
  cv::Size panorama{1100, 110};  // the paper's setting
  cv::Mat a, b;
  Frames() {
    a = panoramaBand(panorama.width, panorama.height);
    b = moved(a, 1.3, 0.4, 0.8);
  }
};

const Frames& frames() {
  static const Frames f;
  return f;
}

/// One frame: measure the current panorama against the previous one, then advance.
void measureAndAdvance(benchmark::State& state, bool rotation_scale) {
  const Frames& f = frames();
  WindowRegistration::Options options = f.options;
  options.estimate_rotation_scale = rotation_scale;
  WindowRegistration registration(f.panorama, options);
  std::vector<WindowMotion> out(registration.windowCount());
  registration.setReference(f.a);
  bool use_b = true;
  for (auto _ : state) {
    registration.measure(use_b ? f.b : f.a, out, true);
    registration.advance();
    benchmark::DoNotOptimize(out.data());
    use_b = !use_b;
  }
  const int windows = registration.windowCount();
  state.counters["windows"] = windows;
  state.counters["per_window"] =
      benchmark::Counter(static_cast<double>(windows), benchmark::Counter::kIsIterationInvariantRate |
                                                           benchmark::Counter::kInvert);
}

void BM_MeasureAdvance_PaperSetting(benchmark::State& state) { measureAndAdvance(state, true); }
void BM_MeasureAdvance_TranslationOnly(benchmark::State& state) { measureAndAdvance(state, false); }

/// The pipeline's second pass: re-registering a warped copy against the same reference.
void BM_MeasureKeepAsNextFalse(benchmark::State& state) {
  const Frames& f = frames();
  WindowRegistration registration(f.panorama, f.options);
  std::vector<WindowMotion> out(registration.windowCount());
  registration.setReference(f.a);
  for (auto _ : state) {
    registration.measure(f.b, out, false);
    benchmark::DoNotOptimize(out.data());
  }
}

BENCHMARK(BM_MeasureAdvance_PaperSetting)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MeasureAdvance_TranslationOnly)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_MeasureKeepAsNextFalse)->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
