// The window FFT with its v-direction stage shared across the panorama (ColumnSpectra +
// WindowSpectrum) gives the spectrum, mean and energy of the direct route: the tapered,
// mean-free window zero-padded and transformed by FftPlan::realToComplex. Windows inside the
// panorama and wrapping around u, an odd window length, widths with and without a narrower
// last chunk, and NaN input.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

#include "registration/column_spectra.hpp"
#include "runtime/fft_plan.hpp"

namespace omnipose::registration {
namespace {

struct Direct {
  FftwArray<Complex> spectrum;
  double mean = 0.0, energy = 0.0;
};

/// The reference route, in double where it matters: window k of `image` (rows x width,
/// row-major), h_i h_j (x_ij - m), zero-padded to n x n, one 2-D r2c transform.
Direct directSpectrum(const std::vector<float>& image, int width, const std::vector<float>& taper,
                      int n, int first_col) {
  const int length = static_cast<int>(taper.size());
  double weighted = 0.0, weight = 0.0;
  for (int i = 0; i < length; ++i)
    for (int j = 0; j < length; ++j) {
      const double w = static_cast<double>(taper[i]) * taper[j];
      weighted += w * image[static_cast<std::size_t>(i) * width + (first_col + j) % width];
      weight += w;
    }
  Direct d;
  d.mean = weighted / weight;
  FftwArray<float> window(static_cast<std::size_t>(n) * n);
  d.spectrum = FftwArray<Complex>(static_cast<std::size_t>(n) * (n / 2 + 1));
  const FftPlan plan = FftPlan::realToComplex(n, n, window.data(), d.spectrum.data());
  window.clear();
  for (int i = 0; i < length; ++i)
    for (int j = 0; j < length; ++j) {
      const double x = image[static_cast<std::size_t>(i) * width + (first_col + j) % width];
      const double v = static_cast<double>(taper[i]) * taper[j] * (x - d.mean);
      window[static_cast<std::size_t>(i) * n + j] = static_cast<float>(v);
      d.energy += v * v;
    }
  plan.execute();
  return d;
}

std::vector<float> hann(int length) {
  std::vector<float> h(length);
  for (int i = 0; i < length; ++i)
    h[i] = static_cast<float>(0.5 - 0.5 * std::cos(2.0 * M_PI * (i + 0.5) / length));
  return h;
}

/// Texture with a large mean (grey levels), as a panorama has: the mean removal matters.
std::vector<float> randomImage(int rows, int width, unsigned seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> grey(0.0f, 255.0f);
  std::vector<float> image(static_cast<std::size_t>(rows) * width);
  for (float& x : image) x = grey(rng);
  return image;
}

void expectSameAsDirect(int width, int length, int n, const std::vector<int>& first_cols) {
  SCOPED_TRACE("W " + std::to_string(width) + ", L " + std::to_string(length) + ", n " +
               std::to_string(n));
  const std::vector<float> taper = hann(length);
  const std::vector<float> image = randomImage(length, width, 11 + width + length);
  ColumnSpectra columns(width, n, taper, PlanEffort::kMeasure);
  for (int c = 0; c < columns.chunks(); ++c) columns.transformChunk(image.data(), width, c);
  WindowSpectrum window(n, PlanEffort::kMeasure);
  FftwArray<Complex> spectrum(static_cast<std::size_t>(n) * (n / 2 + 1));
  for (int first_col : first_cols) {
    SCOPED_TRACE("first column " + std::to_string(first_col));
    const Direct d = directSpectrum(image, width, taper, n, first_col);
    const WindowSpectrum::Stats stats = window.transform(columns, first_col, spectrum.data());
    EXPECT_NEAR(stats.mean, d.mean, 1e-5 * std::abs(d.mean));
    EXPECT_NEAR(stats.energy, d.energy, 1e-5 * d.energy);
    ASSERT_GT(d.energy, 0.0);
    float scale = 0.0f;
    for (std::size_t i = 0; i < spectrum.size(); ++i) scale = std::max(scale, std::abs(d.spectrum[i]));
    ASSERT_GT(scale, 0.0f);
    float worst = 0.0f;
    std::size_t worst_bin = 0;
    for (std::size_t i = 0; i < spectrum.size(); ++i)
      if (std::abs(spectrum[i] - d.spectrum[i]) > worst) {
        worst = std::abs(spectrum[i] - d.spectrum[i]);
        worst_bin = i;
      }
    EXPECT_EQ(spectrum[0], Complex(0.0f, 0.0f)) << "the mean-free window's DC";
    EXPECT_LE(worst, 2e-6f * scale) << "bin " << worst_bin << " of " << spectrum.size()
                                    << ": " << spectrum[worst_bin] << " vs " << d.spectrum[worst_bin];
  }
}

TEST(ColumnSpectra, WindowSpectrumMatchesTheDirectTransformInsideAndAcrossTheSeam) {
  // 300 columns: chunks of 128, 128 and 44; windows at the start, inside, ending at the last
  // column, and wrapping around u.
  expectSameAsDirect(300, 110, 112, {0, 37, 190, 250, 299});
}

TEST(ColumnSpectra, WidthsThatFillTheirChunksAndOddWindowLengths) {
  expectSameAsDirect(256, 110, 112, {0, 146, 200});
  expectSameAsDirect(100, 45, 48, {0, 55, 80});
  expectSameAsDirect(45, 45, 48, {0, 20});  // the window is the whole panorama
}

TEST(ColumnSpectra, NanInputMakesMeanAndEnergyNan) {
  constexpr int kWidth = 200, kLength = 40, kN = 40;
  const std::vector<float> taper = hann(kLength);
  std::vector<float> image = randomImage(kLength, kWidth, 3);
  image[static_cast<std::size_t>(10) * kWidth + 150] = std::numeric_limits<float>::quiet_NaN();
  ColumnSpectra columns(kWidth, kN, taper, PlanEffort::kMeasure);
  for (int c = 0; c < columns.chunks(); ++c) columns.transformChunk(image.data(), kWidth, c);
  WindowSpectrum window(kN, PlanEffort::kMeasure);
  FftwArray<Complex> spectrum(static_cast<std::size_t>(kN) * (kN / 2 + 1));
  const WindowSpectrum::Stats hit = window.transform(columns, 130, spectrum.data());
  EXPECT_TRUE(std::isnan(hit.mean));
  EXPECT_TRUE(std::isnan(hit.energy));
  // A window that does not contain the NaN column is unaffected.
  const WindowSpectrum::Stats clear = window.transform(columns, 10, spectrum.data());
  EXPECT_TRUE(std::isfinite(clear.mean));
  EXPECT_TRUE(std::isfinite(clear.energy));
  EXPECT_GT(clear.energy, 0.0);
}

TEST(ColumnSpectra, RejectsSizesItCannotServe) {
  const std::vector<float> taper = hann(50);
  EXPECT_THROW(ColumnSpectra(40, 64, taper, PlanEffort::kMeasure), std::invalid_argument);  // L > W
  EXPECT_THROW(ColumnSpectra(100, 48, taper, PlanEffort::kMeasure), std::invalid_argument);  // L > n
  EXPECT_THROW(ColumnSpectra(100, 63, taper, PlanEffort::kMeasure), std::invalid_argument);  // odd n
  EXPECT_THROW(WindowSpectrum(63, PlanEffort::kMeasure), std::invalid_argument);
}

}  // namespace
}  // namespace omnipose::registration
