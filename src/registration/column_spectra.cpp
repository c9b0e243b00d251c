#include "registration/column_spectra.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <numbers>
#include <stdexcept>
#include <utility>

#include "runtime/simd.hpp"

namespace omnipose::registration {

using runtime::fftwPlannerMutex;
using runtime::planFlags;
namespace simd = runtime::simd;
namespace {

/// Columns per chunk of the column stage: a multiple of 8, so every chunk's arrays have the
/// alignment the plans were made for (32 bytes of floats and of complex values).
constexpr int kChunkWidth = 128;

fftwf_complex* fftw(Complex* z) { return reinterpret_cast<fftwf_complex*>(z); }

std::size_t roundUp(std::size_t x, std::size_t multiple) {
  return (x + multiple - 1) / multiple * multiple;
}

void destroy(fftwf_plan& plan) {
  if (plan == nullptr) return;
  std::lock_guard lock(fftwPlannerMutex());
  fftwf_destroy_plan(std::exchange(plan, nullptr));
}

}  // namespace

ColumnSpectra::ColumnSpectra(int width, int fft_size, std::span<const float> taper,
                             PlanEffort effort)
    : width_(width),
      n_(fft_size),
      bins_(fft_size / 2 + 1),
      taper_(taper.begin(), taper.end()),
      chunk_width_(kChunkWidth),
      chunks_((width + kChunkWidth - 1) / kChunkWidth) {
  const int length = static_cast<int>(taper.size());
  if (width < 1 || fft_size < 2 || fft_size % 2 != 0 || length < 1 || length > fft_size ||
      length > width)
    throw std::invalid_argument("ColumnSpectra: bad sizes");
  band_stride_ = roundUp(static_cast<std::size_t>(width), kChunkWidth);
  row_stride_ = roundUp(static_cast<std::size_t>(width) + length - 1, 8);
  band_ = FftwArray<float>(static_cast<std::size_t>(n_) * band_stride_);
  spectra_ = FftwArray<Complex>(static_cast<std::size_t>(bins_) * row_stride_);

  taper_spectrum_.resize(bins_);
  for (int kv = 0; kv < bins_; ++kv) {
    double re = 0.0, im = 0.0;
    for (int i = 0; i < length; ++i) {
      const double angle = -2.0 * std::numbers::pi * kv * i / n_;
      re += taper_[i] * std::cos(angle);
      im += taper_[i] * std::sin(angle);
    }
    taper_spectrum_[kv] = Complex(static_cast<float>(re), static_cast<float>(im));
  }
  paired_taper_.resize(2 * static_cast<std::size_t>(length));
  for (int i = 0; i < length; ++i) {
    paired_taper_[2 * i] = paired_taper_[2 * i + 1] = taper_[i];
    taper_sum_ += taper_[i];
  }

  const unsigned flags = planFlags(effort);
  const int last_width = width - (chunks_ - 1) * chunk_width_;
  const bool needs_full = chunks_ > 1 || last_width == chunk_width_;
  const bool needs_last = last_width != chunk_width_;
  {
    std::lock_guard lock(fftwPlannerMutex());
    const auto plan = [&](int count, std::size_t offset) {
      return fftwf_plan_many_dft_r2c(1, &n_, count, band_.data() + offset, nullptr,
                                     static_cast<int>(band_stride_), 1,
                                     fftw(spectra_.data() + offset), nullptr,
                                     static_cast<int>(row_stride_), 1, flags);
    };
    if (needs_full) full_ = plan(chunk_width_, 0);
    if (needs_last) last_ = plan(last_width, static_cast<std::size_t>(chunks_ - 1) * chunk_width_);
  }
  if ((needs_full && full_ == nullptr) || (needs_last && last_ == nullptr)) {
    destroy(full_);
    destroy(last_);
    throw std::runtime_error("FFTW could not plan the panorama's column transforms");
  }
  // Planning wrote into the arrays; rows L .. n - 1 of the band are the zero padding.
  band_.clear();
  spectra_.clear();
}

ColumnSpectra::~ColumnSpectra() {
  destroy(full_);
  destroy(last_);
}

OMNIPOSE_SIMD_CLONES
void ColumnSpectra::transformChunk(const float* first_row, std::size_t stride, int chunk) {
  const int u0 = chunk * chunk_width_;
  const int count = std::min(chunk_width_, width_ - u0);
  const int length = static_cast<int>(taper_.size());
  // Band row i = h_i times panorama row i, this chunk's columns.
  for (int i = 0; i < length; ++i) {
    const float* src = first_row + static_cast<std::size_t>(i) * stride + u0;
    float* dst = band_.data() + static_cast<std::size_t>(i) * band_stride_ + u0;
    const simd::F4 h = simd::broadcast(taper_[i]);
    int u = 0;
    for (; u + 4 <= count; u += 4) simd::store(dst + u, h * simd::load(src + u));
    for (; u < count; ++u) dst[u] = taper_[i] * src[u];
  }
  fftwf_execute_dft_r2c(count == chunk_width_ ? full_ : last_, band_.data() + u0,
                        fftw(spectra_.data() + u0));
  // Columns 0 .. L - 2 again after column W - 1, for the windows that wrap around u.
  const int wrap_end = std::min(u0 + count, length - 1);
  if (u0 < wrap_end) {
    for (int kv = 0; kv < bins_; ++kv) {
      Complex* r = spectra_.data() + static_cast<std::size_t>(kv) * row_stride_;
      std::memcpy(r + width_ + u0, r + u0, sizeof(Complex) * (wrap_end - u0));
    }
  }
}

WindowSpectrum::WindowSpectrum(int fft_size, PlanEffort effort)
    : n_(fft_size),
      rows_(static_cast<std::size_t>(fft_size / 2 + 1) * fft_size),
      spectra_(rows_.size()) {
  if (fft_size < 2 || fft_size % 2 != 0) throw std::invalid_argument("WindowSpectrum: bad size");
  {
    std::lock_guard lock(fftwPlannerMutex());
    plan_ = fftwf_plan_many_dft(1, &n_, n_ / 2 + 1, fftw(rows_.data()), nullptr, 1, n_,
                                fftw(spectra_.data()), nullptr, 1, n_, FFTW_FORWARD,
                                planFlags(effort));
  }
  if (plan_ == nullptr) throw std::runtime_error("FFTW could not plan the window row transforms");
  rows_.clear();
}

WindowSpectrum::~WindowSpectrum() { destroy(plan_); }

OMNIPOSE_SIMD_CLONES
WindowSpectrum::Stats WindowSpectrum::transform(const ColumnSpectra& columns, int first_col,
                                                Complex* spectrum) {
  const int n = n_, bins = n / 2 + 1, length = columns.length();
  const float* paired = columns.pairedTaper();
  // m = sum_ij h_i h_j x_ij / (sum h)^2, where sum_i h_i x_ij = C_j(0) (real).
  Stats stats;
  {
    const Complex* dc = columns.row(0) + first_col;
    double weighted = 0.0;
    for (int j = 0; j < length; ++j) weighted += static_cast<double>(paired[2 * j]) * dc[j].real();
    stats.mean = weighted / (columns.taperSum() * columns.taperSum());
  }
  // Row k_v: y_j = h_j (C_j(k_v) - m H(k_v)), the v-spectrum of column j of the tapered,
  // mean-free window; Parseval along v gives the window's energy: sum_i y_i^2 =
  // (1/n) sum over all n frequencies, i.e. rows 0 and n/2 once, the others twice.
  double energy = 0.0;
  for (int kv = 0; kv < bins; ++kv) {
    const Complex mh = static_cast<float>(stats.mean) * columns.taperSpectrum(kv);
    const simd::F4 mh4{mh.real(), mh.imag(), mh.real(), mh.imag()};
    const float* c = reinterpret_cast<const float*>(columns.row(kv) + first_col);
    float* y = reinterpret_cast<float*>(rows_.data() + static_cast<std::size_t>(kv) * n);
    // Two running sums (one chain of additions would wait on each one's latency).
    simd::F4 sum4 = simd::broadcast(0.0f), sum4b = simd::broadcast(0.0f);
    // y at floats [f, f + 4), stored; returns its squares.
    const auto taper4 = [&](int f) {
      const simd::F4 v = (simd::load(c + f) - mh4) * simd::load(paired + f);
      simd::store(y + f, v);
      return v * v;
    };
    int f = 0;  // float index: 2 per complex value
    for (; f + 8 <= 2 * length; f += 8) {
      sum4 += taper4(f);
      sum4b += taper4(f + 4);
    }
    sum4 += sum4b;
    for (; f + 4 <= 2 * length; f += 4) sum4 += taper4(f);
    float tail = 0.0f;
    for (; f < 2 * length; f += 2) {  // an odd L: the last value
      y[f] = paired[f] * (c[f] - mh.real());
      y[f + 1] = paired[f] * (c[f + 1] - mh.imag());
      tail += y[f] * y[f] + y[f + 1] * y[f + 1];
    }
    std::fill(y + 2 * length, y + 2 * n, 0.0f);  // zero padding
    const double weight = (kv == 0 || kv == n / 2) ? 1.0 : 2.0;
    energy += weight * (static_cast<double>(simd::sum(sum4)) + tail);
  }
  stats.energy = energy / n;
  fftwf_execute(plan_);
  // The (0, 0) bin is sum_j y_j(0): zero, the mean being removed, but computed as the
  // difference of two sums of L^2 grey levels it keeps their float rounding (~1e-6 of the
  // window's DC). Below the whitening floor, that alone would become a bin of phase noise.
  spectra_[0] = Complex(0.0f, 0.0f);
  // Rows k_v <= n/2: their first n/2 + 1 u-frequencies. Rows k_v > n/2 from Hermitian
  // symmetry: F(k_v, k_u) = conj F(n - k_v, n - k_u) (indices mod n).
  for (int kv = 0; kv < bins; ++kv)
    std::memcpy(spectrum + static_cast<std::size_t>(kv) * bins,
                spectra_.data() + static_cast<std::size_t>(kv) * n, sizeof(Complex) * bins);
  const simd::F4 conjugate{1.0f, -1.0f, 1.0f, -1.0f};
  for (int kv = bins; kv < n; ++kv) {
    const Complex* src = spectra_.data() + static_cast<std::size_t>(n - kv) * n;
    Complex* dst = spectrum + static_cast<std::size_t>(kv) * bins;
    dst[0] = std::conj(src[0]);
    int ku = 1;
    // (dst[ku], dst[ku + 1]) = conj(src[n - ku], src[n - ku - 1]): one load, swapped halves.
    for (; ku + 2 <= bins; ku += 2) {
      const simd::F4 pair = simd::load(reinterpret_cast<const float*>(src + (n - ku - 1)));
      simd::store(reinterpret_cast<float*>(dst + ku),
                  __builtin_shuffle(pair, simd::I4{2, 3, 0, 1}) * conjugate);
    }
    for (; ku < bins; ++ku) dst[ku] = std::conj(src[n - ku]);
  }
  return stats;
}

}  // namespace omnipose::registration
