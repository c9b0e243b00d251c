#include "registration/phase_correlator.hpp"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <initializer_list>
#include <limits>
#include <numbers>

#include "runtime/simd.hpp"
#include "registration/subpixel_peak.hpp"

namespace omnipose::registration {

namespace simd = runtime::simd;
namespace {

/// W below exp(-kBandCut^2 / 2) ~ 1.1% is dropped from the band. A narrower band (2.5)
/// truncates the Gaussian so that it rings, and the sub-sample peak fit reads the ringing
/// (accuracy far worse: docs/PERFORMANCE.md).
constexpr double kBandCut = 3.0;

/// Band size for one axis: keep frequencies with sigma * w <= kBandCut, i.e.
/// |k| <= kBandCut * n / (2 pi sigma), so s >= kBandCut * n / (pi sigma).
int bandLength(int n, double sigma) {
  const int s = fastFftSize(static_cast<int>(std::ceil(kBandCut * n / (std::numbers::pi * sigma))));
  return std::min(s, n);
}

/// Signed frequency of index i on a periodic axis of size n: 0, 1, .., n/2-1, -n/2, .., -1.
int signedIndex(int i, int n) { return i < n / 2 ? i : i - n; }

/// Software prefetch distance of the band loops: 512 floats (2 KiB, 32 cache lines) ahead.
/// The bands a frame keeps for the next one (55 windows x 72 KB at the paper setting, more
/// than a core's L2) are written by whiten() and read back by crossPower() a frame later,
/// from L3 or memory; with the hardware prefetcher alone, crossPower() took 9 % of the wall
/// time for 5 % of the instructions, waiting on those loads (perf, 1 thread; the gain is in
/// docs/PERFORMANCE.md).
constexpr int kPrefetchFloats = 512;
constexpr int kFloatsPerLine = 16;  ///< 64-byte cache lines

/// Prefetches the cache lines of the `count` floats kPrefetchFloats after p, for reading
/// (kWrite 0) or writing (kWrite 1). They may lie past the end of p's array (the next
/// window's band, or nothing): a prefetch never faults, and the addresses are computed as
/// integers, not as pointers out of the array.
template <int kWrite>
void prefetchAhead(const float* p, int count) {
  const auto ahead = reinterpret_cast<std::uintptr_t>(p) + kPrefetchFloats * sizeof(float);
  for (int i = 0; i < count; i += kFloatsPerLine)
    __builtin_prefetch(reinterpret_cast<const void*>(ahead + i * sizeof(float)), kWrite);
}

/// What PhaseCorrelator::whiten() reads of the correlator.
struct WhitenShape {
  int n0, n1, s0, band_cols;
  const float* sqrt_w2;
  const float* noise_cols;
  const float* noise_rows;
  float noise_power;  ///< added to every bin's |F|^2
};

/// PhaseCorrelator::whiten() for one value of `moments`: inlined into each copy of
/// whiten() (OMNIPOSE_SIMD_CLONES), so the bins loop has no test for it.
template <bool kMoments>
[[gnu::always_inline]] inline PhaseNoise whitenBand(const Complex* spectrum, double mean_power,
                                                    Complex* band, const WhitenShape& shape) {
  const int n0 = shape.n0, n1 = shape.n1, s0 = shape.s0, band_cols = shape.band_cols;
  const int spectrum_cols = n1 / 2 + 1;
  const float floor2 = static_cast<float>(1e-8 * mean_power) + 1e-30f;
  const simd::F4 floor4 = simd::broadcast(floor2);
  const simd::F4 noise4 = simd::broadcast(shape.noise_power);
  // Phase-noise moments (PhaseNoise): 1 / (|F|^2 + noise_power), capped at
  // 1 / (kPhaseNoiseFloor mean_power).
  const float noise_cap = 1.0f / (kPhaseNoiseFloor * static_cast<float>(mean_power) + 1e-30f);
  const simd::F4 noise_cap4 = simd::broadcast(noise_cap);
  // G is summed row by row: per row the column sums of m^2 W1^2 (1, w1, w1^2) / |F|^2,
  // times the row's W0^2 (w0^2, w0, 1) (W is separable).
  const float* c0 = shape.noise_cols;
  const float* c1 = c0 + band_cols;
  const float* c2 = c1 + band_cols;
  double g00 = 0.0, g01 = 0.0, g11 = 0.0;
  // A local row length: the stores (memcpy) may alias the correlator's members, which would
  // otherwise be reloaded on every iteration.
  const int row_floats = 2 * band_cols;
  for (int r = 0; r < s0; ++r) {
    // Band row r is frequency k0 = signedIndex(r, s0), stored at row k0 mod n0.
    const int k0 = signedIndex(r, s0);
    const std::size_t src_row = static_cast<std::size_t>(k0 < 0 ? k0 + n0 : k0);
    const float* src = reinterpret_cast<const float*>(spectrum + src_row * spectrum_cols);
    const float* sw = shape.sqrt_w2 + 2 * static_cast<std::size_t>(r) * band_cols;
    float* dst = reinterpret_cast<float*>(band + static_cast<std::size_t>(r) * band_cols);
    prefetchAhead<1>(dst, row_floats);  // the band's row a few rows on
    // P = sqrt(W) F / sqrt(|F|^2 + noise_power): four bins at a time (one reciprocal square
    // root for four), then two; the same operations per bin either way.
    simd::F4 a0 = simd::broadcast(0.0f), a1 = a0, a2 = a0;
    float t0 = 0.0f, t1 = 0.0f, t2 = 0.0f;
    int f = 0;
    for (; f + 8 <= row_floats; f += 8) {
      const simd::F4 z01 = simd::load(src + f), z23 = simd::load(src + f + 4);
      const simd::F4 inv = simd::rsqrt(simd::max(simd::norms(z01, z23), floor4) + noise4);
      simd::store(dst + f, z01 * (simd::load(sw + f) * simd::lowPairs(inv)));
      simd::store(dst + f + 4, z23 * (simd::load(sw + f + 4) * simd::highPairs(inv)));
      if constexpr (!kMoments) continue;
      const simd::F4 inv2 = simd::min(inv * inv, noise_cap4);
      const int c = f / 2;
      a0 += simd::load(c0 + c) * inv2;
      a1 += simd::load(c1 + c) * inv2;
      a2 += simd::load(c2 + c) * inv2;
    }
    for (; f + 4 <= row_floats; f += 4) {
      const simd::F4 z = simd::load(src + f);
      const simd::F4 inv = simd::rsqrt(simd::max(simd::pairNorm(z), floor4) + noise4);
      simd::store(dst + f, z * (simd::load(sw + f) * inv));
      if constexpr (!kMoments) continue;
      const simd::F4 inv2 = simd::min(inv * inv, noise_cap4);  // bins twice: lanes 0, 2
      const int c = f / 2;
      t0 += c0[c] * inv2[0] + c0[c + 1] * inv2[2];
      t1 += c1[c] * inv2[0] + c1[c + 1] * inv2[2];
      t2 += c2[c] * inv2[0] + c2[c + 1] * inv2[2];
    }
    for (; f < row_floats; f += 2) {
      const float re = src[f], im = src[f + 1];
      const float norm = std::max(re * re + im * im, floor2) + shape.noise_power;
      const float gain = sw[f] / std::sqrt(norm);
      dst[f] = re * gain;
      dst[f + 1] = im * gain;
      if constexpr (!kMoments) continue;
      const float inv2 = std::min(1.0f / norm, noise_cap);
      const int c = f / 2;
      t0 += c0[c] * inv2;
      t1 += c1[c] * inv2;
      t2 += c2[c] * inv2;
    }
    g00 += static_cast<double>(shape.noise_rows[r]) * (simd::sum(a0) + t0);
    g01 += static_cast<double>(shape.noise_rows[s0 + r]) * (simd::sum(a1) + t1);
    g11 += static_cast<double>(shape.noise_rows[2 * s0 + r]) * (simd::sum(a2) + t2);
  }
  return {static_cast<float>(g00), static_cast<float>(g01), static_cast<float>(g11)};
}

}  // namespace

int fastFftSize(int n) {
  for (int m = std::max(n + (n & 1), 2);; m += 2) {
    int r = m;
    for (int p : {2, 3, 5, 7})
      while (r % p == 0) r /= p;
    if (r == 1) return m;
  }
}

PhaseCorrelator::PhaseCorrelator(int n0, int n1, double sigma0, double sigma1,
                                 PlanEffort effort, double max_reach0, double near_reach0)
    : n0_(n0),
      n1_(n1),
      s0_(bandLength(n0, sigma0)),
      s1_(bandLength(n1, sigma1)),
      band_cols_(s1_ / 2 + 1),
      max_reach0_(std::max(max_reach0, 0.0)),
      near_reach0_(std::isfinite(near_reach0) ? std::max(near_reach0, 0.0) : 0.0),
      sqrt_w2_(2 * static_cast<std::size_t>(s0_) * band_cols_),
      noise_cols_(3 * static_cast<std::size_t>(band_cols_)),
      noise_rows_(3 * static_cast<std::size_t>(s0_)),
      band_(static_cast<std::size_t>(s0_) * band_cols_),
      surface_(static_cast<std::size_t>(s0_) * s1_) {
  // Surface rows read by a search of |d0| <= reach: the searched |d0| <= floor(reach / spacing)
  // (SearchRegion) and one more on each side for the sub-sample fit. (The same expression
  // as in peak(), so both round alike.)
  const auto row_reach = [&](double reach) {
    const double reach_rows = reach / spacing0();
    const int rows_read = reach_rows < s0_ ? static_cast<int>(std::floor(reach_rows)) + 1 : s0_;
    return 2 * rows_read + 1 < s0_ ? rows_read : -1;
  };
  inverse_ = FftPlan::complexToReal(s0_, s1_, band_.data(), surface_.data(), effort,
                                    row_reach(max_reach0_));
  if (near_reach0_ > 0.0) {
    near_ = FftPlan::complexToReal(s0_, s1_, band_.data(), surface_.data(), effort,
                                   row_reach(near_reach0_));
    unit_roots_ = FftwArray<Complex>(static_cast<std::size_t>(s0_));
    for (int j = 0; j < s0_; ++j) {
      const double angle = 2.0 * std::numbers::pi * j / s0_;
      unit_roots_[j] = Complex(static_cast<float>(std::cos(angle)), static_cast<float>(std::sin(angle)));
    }
  }
  band_.clear();
  surface_.clear();
  // Gaussian weight W(w) = exp(-(sigma0^2 w0^2 + sigma1^2 w1^2) / 2) on the band.
  const double two_pi = 2.0 * std::numbers::pi;
  double sum_w = 0.0, sum_w2 = 0.0;
  for (int c = 0; c < band_cols_; ++c) {
    const double w1 = two_pi * c / n1_;
    const double m = (c == 0) ? 1.0 : 2.0;
    const double q = c == s1_ / 2 ? 0.0 : m * m * std::exp(-sigma1 * sigma1 * w1 * w1);
    noise_cols_[c] = static_cast<float>(q);
    noise_cols_[band_cols_ + c] = static_cast<float>(q * w1);
    noise_cols_[2 * band_cols_ + c] = static_cast<float>(q * w1 * w1);
  }
  for (int r = 0; r < s0_; ++r) {
    const double w0 = two_pi * signedIndex(r, s0_) / n0_;
    const double q = r == s0_ / 2 ? 0.0 : std::exp(-sigma0 * sigma0 * w0 * w0);
    noise_rows_[r] = static_cast<float>(q * w0 * w0);
    noise_rows_[s0_ + r] = static_cast<float>(q * w0);
    noise_rows_[2 * s0_ + r] = static_cast<float>(q);
  }
  for (int r = 0; r < s0_; ++r) {
    const double w0 = two_pi * signedIndex(r, s0_) / n0_;
    for (int c = 0; c < band_cols_; ++c) {
      const double w1 = two_pi * c / n1_;
      const bool nyquist = (r == s0_ / 2) || (c == s1_ / 2);
      const double w =
          nyquist ? 0.0 : std::exp(-0.5 * (sigma0 * sigma0 * w0 * w0 + sigma1 * sigma1 * w1 * w1));
      const std::size_t bin = static_cast<std::size_t>(r) * band_cols_ + c;
      sqrt_w2_[2 * bin] = sqrt_w2_[2 * bin + 1] = static_cast<float>(std::sqrt(w));
      const double multiplicity = (c == 0) ? 1.0 : 2.0;  // Hermitian partner (-k) of c > 0
      sum_w += multiplicity * w;
      sum_w2 += multiplicity * w * w;
    }
  }
  weight_sum_ = sum_w;
  noise_sigma_ = std::sqrt(sum_w2) / sum_w;
}

PeakCovariance PhaseCorrelator::shiftCovariance(const PhaseNoise& ref, const PhaseNoise& cur,
                                                double noise_energy,
                                                const CorrelationPeak& peak) const {
  // Cov = noise_energy / 2 * H^-1 G H^-1 (phase_correlator.hpp), G = G_ref + G_cur, H the
  // peak's curvature in the surface's own units (sum of W, not of ideal heights).
  const double g00 = static_cast<double>(ref.g00) + cur.g00;
  const double g01 = static_cast<double>(ref.g01) + cur.g01;
  const double g11 = static_cast<double>(ref.g11) + cur.g11;
  const double h00 = peak.curvature00 * weight_sum_, h11 = peak.curvature11 * weight_sum_;
  double h01 = peak.curvature01 * weight_sum_;
  const double k = 0.5 * noise_energy;
  if (!(h00 > 0.0) || !(h11 > 0.0) || !(h00 * h11 - h01 * h01 > 0.0)) h01 = 0.0;
  if (!(h00 > 0.0) || !(h11 > 0.0)) {
    const auto alone = [&](double h, double g) {
      return h > 0.0 ? std::min(k * g / (h * h), kNoCurvatureVariance) : kNoCurvatureVariance;
    };
    return {alone(h00, g00), 0.0, alone(h11, g11)};
  }
  const double det = h00 * h11 - h01 * h01;
  const double a = h11 / det, b = -h01 / det, d = h00 / det;  // H^-1
  // M = H^-1 G, then M H^-1 (symmetric).
  const double m00 = a * g00 + b * g01, m01 = a * g01 + b * g11;
  const double m10 = b * g00 + d * g01, m11 = b * g01 + d * g11;
  PeakCovariance c{k * (m00 * a + m01 * b), k * (m00 * b + m01 * d), k * (m10 * b + m11 * d)};
  if (!(c.c00 < kNoCurvatureVariance) || !(c.c11 < kNoCurvatureVariance)) {
    c.c00 = std::min(c.c00, kNoCurvatureVariance);
    c.c11 = std::min(c.c11, kNoCurvatureVariance);
    c.c01 = 0.0;
  }
  return c;
}

OMNIPOSE_SIMD_CLONES
PhaseNoise PhaseCorrelator::whiten(const Complex* spectrum, double mean_power, Complex* band,
                                   bool moments, double noise_power) const {
  const WhitenShape shape{n0_, n1_, s0_, band_cols_, sqrt_w2_.data(), noise_cols_.data(),
                          noise_rows_.data(), static_cast<float>(std::max(noise_power, 0.0))};
  return moments ? whitenBand<true>(spectrum, mean_power, band, shape)
                 : whitenBand<false>(spectrum, mean_power, band, shape);
}

OMNIPOSE_SIMD_CLONES
void PhaseCorrelator::crossPower(const Complex* ref, const Complex* cur, int shift_rows) {
  // Q = W * F_ref * conj(F_cur) / (|F_ref| |F_cur|); both inputs already carry sqrt(W) / |F|.
  const float* a = reinterpret_cast<const float*>(ref);
  const float* b = reinterpret_cast<const float*>(cur);
  float* q = reinterpret_cast<float*>(band_.data());
  if (shift_rows == 0) {
    const std::size_t floats = 2 * band_.size();
    std::size_t f = 0;
    const auto product = [&](std::size_t g) {
      simd::store(q + g, simd::mulConj(simd::load(a + g), simd::load(b + g)));
    };
    static_assert(kFloatsPerLine == 16);
    for (; f + kFloatsPerLine <= floats; f += kFloatsPerLine) {  // a cache line per step
      prefetchAhead<0>(a + f, 1);
      product(f);
      product(f + 4);
      product(f + 8);
      product(f + 12);
    }
    for (; f + 4 <= floats; f += 4) product(f);
    for (; f < floats; f += 2) {
      q[f] = a[f] * b[f] + a[f + 1] * b[f + 1];
      q[f + 1] = a[f + 1] * b[f] - a[f] * b[f + 1];
    }
    return;
  }
  // Row by row, times the row's ramp factor z = exp(+i 2 pi r c / s0) (band row r is
  // frequency r mod s0): Q z = mulConj(Q, conj(z)).
  const int row_floats = 2 * band_cols_;
  for (int r = 0; r < s0_; ++r) {
    const long phase = (static_cast<long>(r) * shift_rows) % s0_;
    const Complex z = unit_roots_[static_cast<std::size_t>(phase < 0 ? phase + s0_ : phase)];
    const simd::F4 z_conj{z.real(), -z.imag(), z.real(), -z.imag()};
    const std::size_t row = static_cast<std::size_t>(r) * row_floats;
    prefetchAhead<0>(a + row, row_floats);
    int f = 0;
    for (; f + 4 <= row_floats; f += 4)
      simd::store(q + row + f, simd::mulConj(simd::mulConj(simd::load(a + row + f), simd::load(b + row + f)), z_conj));
    for (; f < row_floats; f += 2) {
      const float* x = a + row + f;
      const float* y = b + row + f;
      const float re = x[0] * y[0] + x[1] * y[1], im = x[1] * y[0] - x[0] * y[1];
      q[row + f] = re * z.real() - im * z.imag();
      q[row + f + 1] = im * z.real() + re * z.imag();
    }
  }
}

CorrelationPeak PhaseCorrelator::peak(double reach0, double reach1, int offset_rows) const {
  const SurfaceView view{surface_.data(), s0_, s1_};
  const SearchRegion region = SearchRegion::around(view, reach0, reach1);
  const SubpixelPeak p = findPeak(view, region);

  CorrelationPeak out;
  double x0 = p.x0;
  if (offset_rows != 0) {  // back onto one period, [-s0/2, s0/2)
    x0 += offset_rows;
    if (x0 >= s0_ / 2) x0 -= s0_;
    if (x0 < -(s0_ / 2)) x0 += s0_;
  }
  out.shift0 = x0 * spacing0();
  out.shift1 = p.x1 * spacing1();
  out.height = p.value / weight_sum_;
  out.on_border = p.on_border;
  out.curvature00 = p.curvature00 / (weight_sum_ * spacing0() * spacing0());
  out.curvature01 = p.curvature01 / (weight_sum_ * spacing0() * spacing1());
  out.curvature11 = p.curvature11 / (weight_sum_ * spacing1() * spacing1());
  // Confidence: height above the expected maximum of a random-phase surface over the
  // searched samples (noise_sigma * sqrt(2 ln M)), rescaled so that a perfect peak is 1.
  const double samples = static_cast<double>(region.count0()) * region.count1();
  const double floor = noise_sigma_ * std::sqrt(2.0 * std::log(std::max(samples, 2.0)));
  out.confidence = std::clamp((out.height - floor) / (1.0 - floor), 0.0, 1.0);
  return out;
}

CorrelationPeak PhaseCorrelator::correlate(const Complex* ref, const Complex* cur, double reach0,
                                           double reach1) {
  crossPower(ref, cur, 0);
  // Correlation surface r(x) = sum_k Q(k) exp(+i 2 pi k x / s), peak at the shift.
  inverse_.execute();
  return peak(std::min(reach0, max_reach0_) / spacing0(), reach1 / spacing1(), 0);
}

CorrelationPeak PhaseCorrelator::correlateNear(const Complex* ref, const Complex* cur,
                                               double centre0, double reach1) {
  if (!(near_reach0_ > 0.0))  // not planned: search everything
    return correlate(ref, cur, std::numeric_limits<double>::infinity(), reach1);
  // The centre as a whole surface row on one period (r(x + c) = sum_k Q(k) z^k exp(..)).
  const double rows = std::isfinite(centre0) ? std::remainder(std::round(centre0 / spacing0()), s0_) : 0.0;
  const int shift = static_cast<int>(rows);
  crossPower(ref, cur, shift);
  near_.execute();
  return peak(near_reach0_ / spacing0(), reach1 / spacing1(), shift);
}

}  // namespace omnipose::registration
