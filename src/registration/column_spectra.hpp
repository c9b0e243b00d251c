#pragma once
/// \file column_spectra.hpp
/// The window FFT in two stages, the first shared by every window of a panorama (private).
///
/// Every window covers the same panorama rows [top, top + L) and the windows differ only in
/// their first column; the taper is separable (h_i h_j) and the 2-D DFT is separable too. So
/// the v-direction transforms are done once per panorama, column by column (ColumnSpectra:
/// W real FFTs of length n of the v-tapered columns), and a window needs only its n/2 + 1
/// u-direction complex FFTs of length n (WindowSpectrum): about half of a full n x n r2c
/// transform per window. The W column FFTs are shared by the W / step windows, `step` real
/// FFTs of length n per window (step 20, n 112: about a tenth of a window's direct
/// transform). The window's taper-weighted mean m is removed in the frequency domain:
/// the v-spectrum of column j of h_i (x_ij - m) is C_j(k_v) - m H(k_v), H the DFT of h.
///
/// The result is the spectrum FftPlan::realToComplex(n, n) gives for the window
/// h_i h_j (x_ij - m) zero-padded to n x n (the same values up to float rounding), in the
/// same layout. Windows with a static mask (non-separable weights) and re-sampled windows
/// have no shared stage: they take the direct transform.

#include <cstddef>
#include <span>
#include <vector>

#include "registration/fft.hpp"

namespace omnipose::registration {

/// Column (v-direction) half spectra of the v-tapered rows [top, top + L) of a W-column
/// panorama: C_u(k_v) = sum_{i < L} h_i x(top + i, u) e^{-2 pi i k_v i / n}, k_v = 0 .. n/2.
class ColumnSpectra {
 public:
  /// width: panorama columns W >= 1; taper: h, length L with 1 <= L <= n; n = fft_size,
  /// even. Plans the column FFTs (FFTW, `effort`). Throws std::invalid_argument on bad sizes.
  ColumnSpectra(int width, int fft_size, std::span<const float> taper, PlanEffort effort);
  ~ColumnSpectra();
  ColumnSpectra(const ColumnSpectra&) = delete;
  ColumnSpectra& operator=(const ColumnSpectra&) = delete;

  /// The columns are transformed in this many chunks of fixed width (independent of the
  /// thread count, so the results are too).
  int chunks() const { return chunks_; }
  /// Transforms chunk `chunk` of the columns of the rows starting at `first_row` (row i at
  /// first_row + i * stride, L rows, W floats each). Distinct chunks may run concurrently
  /// on different threads; all of them must be done before any window is read.
  /// Allocation-free.
  void transformChunk(const float* first_row, std::size_t stride, int chunk);

  /// Row k_v (0 .. n/2) of the column spectra: entry u is C_u(k_v) for u in [0, W + L - 1)
  /// (columns W .. W + L - 2 repeat columns 0 .. L - 2: a window wrapping around u reads
  /// contiguously).
  const Complex* row(int kv) const { return spectra_.data() + static_cast<std::size_t>(kv) * row_stride_; }
  /// H(k_v) = sum_{i < L} h_i e^{-2 pi i k_v i / n}, k_v = 0 .. n/2.
  Complex taperSpectrum(int kv) const { return taper_spectrum_[kv]; }
  /// The taper with every value twice (h_0, h_0, h_1, h_1, ...): one weight per float of a
  /// row of complex values.
  const float* pairedTaper() const { return paired_taper_.data(); }
  /// sum_i h_i (the taper's DC gain).
  double taperSum() const { return taper_sum_; }

  int width() const { return width_; }
  int length() const { return static_cast<int>(taper_.size()); }
  int fftSize() const { return n_; }
  const std::vector<float>& taper() const { return taper_; }

 private:
  int width_, n_, bins_;
  std::vector<float> taper_;
  std::vector<Complex> taper_spectrum_;
  std::vector<float> paired_taper_;
  double taper_sum_ = 0.0;
  int chunk_width_, chunks_;
  std::size_t band_stride_;       ///< floats per row of band_ (>= W)
  std::size_t row_stride_;        ///< complex entries per row of spectra_ (>= W + L - 1)
  FftwArray<float> band_;         ///< n rows: h_i x(top + i, u); rows L .. n - 1 are zero
  FftwArray<Complex> spectra_;    ///< n/2 + 1 rows of row_stride_
  /// Plans for a full chunk and for the last, narrower one (null when W is a multiple of
  /// the chunk width), planned on chunk 0's arrays and run on any chunk's (same alignment).
  fftwf_plan full_ = nullptr, last_ = nullptr;
};

/// One worker's second stage: the u-direction FFTs of one window. Owns its buffers and
/// plan (one per thread). Allocation-free after construction.
class WindowSpectrum {
 public:
  WindowSpectrum(int fft_size, PlanEffort effort);
  ~WindowSpectrum();
  WindowSpectrum(const WindowSpectrum&) = delete;
  WindowSpectrum& operator=(const WindowSpectrum&) = delete;

  struct Stats {
    double mean = 0.0;    ///< taper-weighted mean m of the window's samples
    double energy = 0.0;  ///< sum over the window of (h_i h_j (x_ij - m))^2 (Parseval)
  };
  /// Writes into `spectrum` (n x (n/2 + 1), FftPlan::realToComplex's layout) the spectrum of
  /// the window of columns [first_col, first_col + L) (0 <= first_col < W, wrapping
  /// around u), tapered and with its mean removed. NaN samples make mean and energy NaN.
  Stats transform(const ColumnSpectra& columns, int first_col, Complex* spectrum);

 private:
  int n_;
  FftwArray<Complex> rows_;      ///< n/2 + 1 rows of n: h_j (C_j - m H), zero-padded
  FftwArray<Complex> spectra_;   ///< their u-direction FFTs
  fftwf_plan plan_ = nullptr;
};

}  // namespace omnipose::registration
