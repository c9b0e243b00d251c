// The registration's FFT building blocks (src/registration): an inverse transform that
// computes only the rows near zero shift agrees with the full one on those rows and leaves
// the others alone, and a phase correlator planned for a limited rotation search finds the
// same peak as an unrestricted one.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include "runtime/fft_plan.hpp"
#include "registration/phase_correlator.hpp"

namespace omnipose::registration {
namespace {

/// A random half spectrum of a real rows x cols signal (from its forward transform, so it
/// is Hermitian where it must be).
FftwArray<Complex> randomSpectrum(int rows, int cols, unsigned seed) {
  FftwArray<float> signal(static_cast<std::size_t>(rows) * cols);
  FftwArray<Complex> spectrum(static_cast<std::size_t>(rows) * (cols / 2 + 1));
  const FftPlan forward = FftPlan::realToComplex(rows, cols, signal.data(), spectrum.data());
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.0f, 1.0f);
  for (std::size_t i = 0; i < signal.size(); ++i) signal[i] = noise(rng);
  forward.execute();
  return spectrum;
}

TEST(FftPlan, AnInverseLimitedToRowsNearZeroMatchesTheFullOneThereAndSkipsTheRest) {
  constexpr int kRows = 96, kCols = 64, kReach = 12;
  const FftwArray<Complex> spectrum = randomSpectrum(kRows, kCols, 7);
  FftwArray<Complex> in_full(spectrum.size()), in_part(spectrum.size());
  FftwArray<float> full(static_cast<std::size_t>(kRows) * kCols), part(full.size());
  const FftPlan all_rows = FftPlan::complexToReal(kRows, kCols, in_full.data(), full.data());
  const FftPlan near_rows =
      FftPlan::complexToReal(kRows, kCols, in_part.data(), part.data(), PlanEffort::kMeasure, kReach);
  for (std::size_t i = 0; i < spectrum.size(); ++i) in_full[i] = in_part[i] = spectrum[i];
  const float sentinel = std::numeric_limits<float>::quiet_NaN();
  for (std::size_t i = 0; i < part.size(); ++i) part[i] = sentinel;
  all_rows.execute();
  near_rows.execute();

  float scale = 0.0f;
  for (std::size_t i = 0; i < full.size(); ++i) scale = std::max(scale, std::abs(full[i]));
  ASSERT_GT(scale, 0.0f);
  int computed = 0, skipped = 0;
  for (int r = 0; r < kRows; ++r) {
    const bool near = r <= kReach || r >= kRows - kReach;
    for (int c = 0; c < kCols; ++c) {
      const std::size_t i = static_cast<std::size_t>(r) * kCols + c;
      if (near) {
        EXPECT_NEAR(part[i], full[i], 1e-5f * scale) << "row " << r << ", column " << c;
        ++computed;
      } else {
        EXPECT_TRUE(std::isnan(part[i])) << "row " << r << " was computed";
        ++skipped;
      }
    }
  }
  EXPECT_EQ(computed, (2 * kReach + 1) * kCols);
  EXPECT_EQ(skipped, (kRows - 2 * kReach - 1) * kCols);
  // The input is kept (the caller's band is reused).
  for (std::size_t i = 0; i < spectrum.size(); ++i) ASSERT_EQ(in_part[i], spectrum[i]) << i;
}

TEST(FftPlan, AReachCoveringEveryRowComputesEveryRow) {
  constexpr int kRows = 16, kCols = 8;
  const FftwArray<Complex> spectrum = randomSpectrum(kRows, kCols, 3);
  // Reach 7 leaves out row 8 (shift -8) alone; 8 and beyond cover every row.
  for (int reach : {7, 8, 100}) {
    FftwArray<Complex> in(spectrum.size());
    FftwArray<float> out(static_cast<std::size_t>(kRows) * kCols);
    const FftPlan plan =
        FftPlan::complexToReal(kRows, kCols, in.data(), out.data(), PlanEffort::kMeasure, reach);
    for (std::size_t i = 0; i < spectrum.size(); ++i) in[i] = spectrum[i];
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = std::numeric_limits<float>::quiet_NaN();
    plan.execute();
    for (std::size_t i = 0; i < out.size(); ++i) {
      const bool skipped = reach == 7 && i / kCols == 8;
      ASSERT_EQ(std::isnan(out[i]), skipped) << "reach " << reach << ", sample " << i;
    }
  }
}

/// A smooth random texture sampled at (r + dr, c + dc), periodic in both axes.
std::vector<float> texture(int rows, int cols, double dr, double dc) {
  std::vector<float> out(static_cast<std::size_t>(rows) * cols);
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> phase(0.0, 2.0 * std::numbers::pi);
  struct Wave { int k0, k1; double phi; };
  std::vector<Wave> waves;
  for (int k0 = -6; k0 <= 6; ++k0)
    for (int k1 = 0; k1 <= 6; ++k1) waves.push_back({k0, k1, phase(rng)});
  for (int r = 0; r < rows; ++r)
    for (int c = 0; c < cols; ++c) {
      double v = 0.0;
      for (const Wave& w : waves)
        v += std::cos(2.0 * std::numbers::pi * (w.k0 * (r + dr) / rows + w.k1 * (c + dc) / cols) + w.phi);
      out[static_cast<std::size_t>(r) * cols + c] = static_cast<float>(v);
    }
  return out;
}

/// The whitened band of a rows x cols image, as the registration makes it: forward r2c,
/// then `correlator`'s whitening (the energy is the spectrum's mean power, by Parseval).
class Whitener {
 public:
  Whitener(int rows, int cols, const PhaseCorrelator& correlator)
      : signal_(static_cast<std::size_t>(rows) * cols),
        spectrum_(static_cast<std::size_t>(rows) * (cols / 2 + 1)),
        forward_(FftPlan::realToComplex(rows, cols, signal_.data(), spectrum_.data())),
        correlator_(correlator) {}

  void operator()(const std::vector<float>& image, FftwArray<Complex>& band,
                  double noise_power = 0.0) {
    double power = 0.0;
    for (std::size_t i = 0; i < signal_.size(); ++i) {
      signal_[i] = image[i];
      power += static_cast<double>(signal_[i]) * signal_[i];
    }
    forward_.execute();
    correlator_.whiten(spectrum_.data(), power, band.data(), true, noise_power);
  }
  /// The last image's spectrum (rows x (cols/2 + 1)).
  const FftwArray<Complex>& spectrum() const { return spectrum_; }

 private:
  FftwArray<float> signal_;
  FftwArray<Complex> spectrum_;
  FftPlan forward_;
  const PhaseCorrelator& correlator_;
};

TEST(PhaseCorrelator, APlanLimitedToTheSearchedRowsFindsTheSamePeak) {
  constexpr int kRows = 96, kCols = 64;
  // Content at x in `cur` appears at x + d in `ref`: ref(x) = cur(x - d).
  const double d0 = -4.3, d1 = 2.6;
  const std::vector<float> cur = texture(kRows, kCols, 0.0, 0.0);
  const std::vector<float> ref = texture(kRows, kCols, -d0, -d1);
  PhaseCorrelator full(kRows, kCols, 1.0, 1.0);
  PhaseCorrelator limited(kRows, kCols, 1.0, 1.0, PlanEffort::kMeasure, 10.7);
  ASSERT_EQ(full.bandSize(), limited.bandSize());

  Whitener whitened(kRows, kCols, full);
  FftwArray<Complex> band_ref(full.bandSize()), band_cur(full.bandSize());
  whitened(ref, band_ref);
  whitened(cur, band_cur);
  const CorrelationPeak a = full.correlate(band_ref.data(), band_cur.data(), 10.7, 6.0);
  const CorrelationPeak b = limited.correlate(band_ref.data(), band_cur.data(), 10.7, 6.0);
  EXPECT_NEAR(a.shift0, d0, 0.05);
  EXPECT_NEAR(a.shift1, d1, 0.05);
  EXPECT_NEAR(b.shift0, a.shift0, 1e-5);
  EXPECT_NEAR(b.shift1, a.shift1, 1e-5);
  EXPECT_NEAR(b.height, a.height, 1e-5);
  EXPECT_NEAR(b.confidence, a.confidence, 1e-5);
  EXPECT_EQ(b.on_border, a.on_border);
  // A larger reach is capped at the planned one: a shift beyond it is not found.
  whitened(texture(kRows, kCols, 14.0, 0.0), band_ref);  // d0 = -14
  const CorrelationPeak unrestricted = full.correlate(band_ref.data(), band_cur.data(), 20.0, 6.0);
  EXPECT_NEAR(unrestricted.shift0, -14.0, 0.05);
  const CorrelationPeak capped = limited.correlate(band_ref.data(), band_cur.data(), 20.0, 6.0);
  EXPECT_LE(std::abs(capped.shift0), 11.0);
}

TEST(PhaseCorrelator, ASearchNearAGivenRowFindsTheFullSearchPeakThere) {
  constexpr int kRows = 96, kCols = 64;
  constexpr double kNear = 8.0;
  const double inf = std::numeric_limits<double>::infinity();
  PhaseCorrelator full(kRows, kCols, 1.0, 1.0);
  PhaseCorrelator near(kRows, kCols, 1.0, 1.0, PlanEffort::kMeasure, inf, kNear);
  ASSERT_EQ(near.nearReach0(), kNear);
  Whitener whitened(kRows, kCols, full);
  FftwArray<Complex> band_ref(full.bandSize()), band_cur(full.bandSize());
  whitened(texture(kRows, kCols, 0.0, 0.0), band_cur);
  // Shifts far from zero, one across the wrap-around at +-48 rows from its centre row.
  for (const double d0 : {17.4, -44.6, 3.2}) {
    whitened(texture(kRows, kCols, -d0, -2.6), band_ref);
    const CorrelationPeak a = full.correlate(band_ref.data(), band_cur.data(), inf, inf);
    ASSERT_NEAR(a.shift0, d0, 0.05);
    for (const double centre : {d0 - 5.3, d0, d0 + 6.0}) {
      const CorrelationPeak b = near.correlateNear(band_ref.data(), band_cur.data(), centre, inf);
      EXPECT_NEAR(b.shift0, a.shift0, 1e-4) << d0 << " near " << centre;
      EXPECT_NEAR(b.shift1, a.shift1, 1e-4) << d0 << " near " << centre;
      EXPECT_NEAR(b.height, a.height, 1e-4) << d0 << " near " << centre;
      EXPECT_FALSE(b.on_border);
      // Fewer samples searched, a lower noise floor: at least as confident.
      EXPECT_GE(b.confidence, a.confidence - 1e-6);
    }
    // Without a planned band, correlateNear() searches every row.
    const CorrelationPeak unplanned = full.correlateNear(band_ref.data(), band_cur.data(), d0 + 30.0, inf);
    EXPECT_EQ(unplanned.shift0, a.shift0);
    EXPECT_EQ(unplanned.confidence, a.confidence);
    // A band that does not reach the peak does not find it.
    const CorrelationPeak off = near.correlateNear(band_ref.data(), band_cur.data(), d0 + 20.0, inf);
    EXPECT_GT(std::abs(std::remainder(off.shift0 - d0, kRows)), kNear);
    EXPECT_LT(off.height, 0.25 * a.height);  // 0.13 (2026-11-25)
  }
}

}  // namespace
}  // namespace omnipose::registration

namespace omnipose::registration {
namespace {

// whiten()'s noise_power: each band bin keeps |F|^2 / (|F|^2 + noise_power) of its whitened
// power, so the cross-power spectrum weighs a bin the noise dominates by its signal-to-noise
// ratio; a pure shift is still found where it is, under a lower peak.
TEST(PhaseCorrelator, ANoisePowerWeighsEachBinBySignalToNoise) {
  constexpr int kRows = 96, kCols = 64;
  PhaseCorrelator correlator(kRows, kCols, 1.0, 1.0);
  Whitener whitened(kRows, kCols, correlator);
  // Every frequency present: white noise (a wave texture has a few dozen bins).
  std::vector<float> cur(static_cast<std::size_t>(kRows) * kCols);
  std::mt19937 rng(3);
  std::normal_distribution<float> grey(0.0f, 20.0f);
  for (float& x : cur) x = grey(rng);
  FftwArray<Complex> plain(correlator.bandSize()), weighted(correlator.bandSize());
  whitened(cur, plain);
  // The median bin power of the texture: half the bins are below it.
  std::vector<double> powers;
  for (std::size_t i = 0; i < whitened.spectrum().size(); ++i)
    powers.push_back(std::norm(whitened.spectrum()[i]));
  std::nth_element(powers.begin(), powers.begin() + static_cast<std::ptrdiff_t>(powers.size() / 2),
                   powers.end());
  const double noise_power = powers[powers.size() / 2];
  whitened(cur, weighted, noise_power);

  const int s0 = correlator.surfaceRows(), band_cols = correlator.surfaceCols() / 2 + 1;
  int checked = 0;
  double lowest = 1.0;
  for (int r = 0; r < s0; ++r) {
    const int k0 = r < s0 / 2 ? r : r - s0;
    for (int c = 0; c < band_cols; ++c) {
      const std::size_t bin = static_cast<std::size_t>(r) * band_cols + c;
      const double p = std::norm(plain[bin]);
      if (!(p > 1e-6)) continue;  // the band's Nyquist row and column carry no weight
      const double f2 = std::norm(whitened.spectrum()[static_cast<std::size_t>((k0 + kRows) % kRows) *
                                                       (kCols / 2 + 1) + c]);
      const double ratio = std::norm(weighted[bin]) / p;
      EXPECT_NEAR(ratio, f2 / (f2 + noise_power), 2e-3) << "bin " << r << ", " << c;
      // The phase is the signal's.
      EXPECT_NEAR(std::arg(weighted[bin] * std::conj(plain[bin])), 0.0, 1e-3);
      lowest = std::min(lowest, ratio);
      ++checked;
    }
  }
  EXPECT_GT(checked, 1000);
  EXPECT_LT(lowest, 0.1);  // some bins are weighted well down

  const double d0 = -4.3, d1 = 2.6;
  FftwArray<Complex> ref_plain(correlator.bandSize()), ref_weighted(correlator.bandSize());
  const std::vector<float> wave_cur = texture(kRows, kCols, 0.0, 0.0);
  const std::vector<float> wave_ref = texture(kRows, kCols, -d0, -d1);
  whitened(wave_cur, plain);
  whitened(wave_cur, weighted, noise_power);
  whitened(wave_ref, ref_plain);
  whitened(wave_ref, ref_weighted, noise_power);
  const CorrelationPeak a = correlator.correlate(ref_plain.data(), plain.data(), 20.0, 20.0);
  const CorrelationPeak b = correlator.correlate(ref_weighted.data(), weighted.data(), 20.0, 20.0);
  EXPECT_NEAR(b.shift0, d0, 0.05);
  EXPECT_NEAR(b.shift1, d1, 0.05);
  EXPECT_LT(b.height, 0.95 * a.height);
  EXPECT_GT(b.height, 0.3 * a.height);
}

}  // namespace
}  // namespace omnipose::registration
