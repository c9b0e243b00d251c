#pragma once
/// \file phase_correlator.hpp
/// Phase-only correlation of two real n0 x n1 signals given their r2c half-spectra, with a
/// Gaussian spectral weight
///     W(w0, w1) = exp(-(sigma0^2 w0^2 + sigma1^2 w1^2) / 2),   w = 2 pi k / n (rad/sample),
/// so that the correlation peak of a shifted pair is a (periodic) Gaussian of standard
/// deviation sigma samples: a 3-point Gaussian fit per axis is then unbiased, and the weak,
/// noisy high frequencies count less. Bins where W < ~1% are dropped (the "band"), so the
/// correlation surface is only s0 x s1 (s = n when nothing is dropped), sampled every n/s
/// input samples.
///
/// Sign: correlate(ref, cur) peaks at d where content at x in `cur` appears at x + d in
/// `ref` (the same as cv::phaseCorrelate(cur, ref)).

#include <cstddef>
#include <limits>

#include "registration/fft.hpp"

namespace omnipose::registration {

/// Peak of a correlation surface.
struct CorrelationPeak {
  double shift0 = 0.0;     ///< sub-sample shift along axis 0 (rows), input samples
  double shift1 = 0.0;     ///< sub-sample shift along axis 1 (columns), input samples
  double height = 0.0;     ///< fitted peak height / ideal peak height (1 = identical signals)
  double confidence = 0.0; ///< height above the noise floor, mapped to [0, 1]
  bool on_border = false;  ///< the integer peak lies on the border of the searched region
  /// Curvature of the surface at the peak, -(second derivatives), in ideal peak heights per
  /// input sample^2 (axis 0 rows, 1 columns): what shiftCovariance() reads. A peak that is
  /// a ridge along an axis (content along one direction only) has ~0 there.
  double curvature00 = 0.0;
  double curvature01 = 0.0;
  double curvature11 = 0.0;
};

/// How precisely whiten() found a signal's phases: the moments
///     G = sum over the band's bins of m^2 W^2 w w^T / (|F|^2 + noise_power),
/// w = (w0, w1) rad/sample, m = 2 for a bin with a Hermitian partner (c > 0), else 1;
/// |F|^2 floored at kPhaseNoiseFloor times the mean power; noise_power whiten()'s. With
/// additive white noise of energy E|N|^2 per bin, the phase of bin F is off by a random
/// angle of variance E|N|^2 / (2 |F|^2), so G is what a signal contributes to the variance
/// of a correlation peak (shiftCovariance()). With noise_power > 0 the cross-power bin's
/// weight also carries |F|^2 / (|F|^2 + noise_power) of the other signal, taken as 1 here:
/// G is then an upper bound, reached where the other signal stands far above the noise.
/// Zero: not whitened.
struct PhaseNoise {
  float g00 = 0.0f;  ///< sum m^2 W^2 w0^2 / |F|^2
  float g01 = 0.0f;  ///< sum m^2 W^2 w0 w1 / |F|^2
  float g11 = 0.0f;  ///< sum m^2 W^2 w1^2 / |F|^2
};

/// Symmetric 2 x 2 covariance of a correlation peak, input samples^2 (axis 0 = rows).
struct PeakCovariance {
  double c00 = 0.0;
  double c01 = 0.0;
  double c11 = 0.0;
};

/// Power floor of the phase-noise moments, relative to the signal's mean power per bin: a
/// bin emptier than this counts as this (its phase is then random anyway, and an empty bin
/// of a noiseless render would otherwise dominate the sum).
inline constexpr float kPhaseNoiseFloor = 1e-5f;

/// shiftCovariance()'s variance along an axis without curvature, input samples^2: a shift
/// the window does not know (1000 px standard deviation).
inline constexpr double kNoCurvatureVariance = 1e6;

class PhaseCorrelator {
 public:
  /// n0 x n1: size of the real signals (even); sigma0, sigma1: peak width, input samples;
  /// `effort`: how the inverse transform is planned. `max_reach0`: the largest reach0
  /// correlate() will be asked for (input samples; infinity: any): the inverse transform
  /// then computes only the surface rows that search and its sub-sample fit read.
  /// `near_reach0` > 0: correlateNear() is planned too (input samples; a second inverse
  /// transform that computes the 2 floor(near_reach0 / spacing) + 3 surface rows around a
  /// given centre).
  PhaseCorrelator(int n0, int n1, double sigma0, double sigma1,
                  PlanEffort effort = PlanEffort::kMeasure,
                  double max_reach0 = std::numeric_limits<double>::infinity(),
                  double near_reach0 = 0.0);

  /// Number of complex bins a whitened band occupies (s0 * (s1/2 + 1)).
  std::size_t bandSize() const { return band_.size(); }
  int surfaceRows() const { return s0_; }
  int surfaceCols() const { return s1_; }

  /// band = sqrt(W) * F / sqrt(|F|^2 + noise_power) on the band bins of `spectrum`
  /// (n0 x (n1/2+1), from r2c). `mean_power`: mean of |F|^2 over all n0 x n1 bins (= the
  /// signal's energy, by Parseval); |F|^2 is floored at 1e-8 mean_power so near-empty bins
  /// are not amplified. `noise_power`: the noise's expected |F|^2 per bin (sigma^2 times
  /// the sum of the squared taper weights, for pixel noise of variance sigma^2), >= 0. With
  /// 0 every bin is whitened to full weight (pure phase correlation); else a bin the noise
  /// dominates keeps about its signal-to-noise ratio of weight, so the cross-power spectrum
  /// of two such bands weighs each bin by W times the product of the two
  /// |F|^2 / (|F|^2 + noise_power): whitened where the signal stands above the noise,
  /// cross-correlation below it. Allocation-free.
  // A separate band buffer: whitening inside the cross-power loop instead was slower
  // (docs/PERFORMANCE.md).
  /// With `moments` it also returns the signal's phase-noise moments (PhaseNoise, for
  /// shiftCovariance(); 4 % of a frame's instructions), else zero.
  PhaseNoise whiten(const Complex* spectrum, double mean_power, Complex* band,
                    bool moments = true, double noise_power = 0.0) const;
  /// Covariance of `peak` (from correlate(ref, cur)) caused by additive white noise of
  /// energy `noise_energy` per spectral bin in each signal (sigma^2 times the sum of the
  /// squared taper weights, for pixel noise of variance sigma^2). Linearising the surface's
  /// stationarity condition about the true shift d,
  ///     H (d_hat - d) = sum_f m W w sin(eps_f),
  /// with eps_f the phase error of the cross-power bin (variance noise_energy / 2 times
  /// 1/|F_ref|^2 + 1/|F_cur|^2, Hermitian partners in step) and H the surface's curvature
  /// at the peak (sum_f m W w w^T cos(eps_f): only the bins whose phases agree curve it), so
  ///     Cov = noise_energy / 2 * H^-1 (G_ref + G_cur) H^-1.
  /// A window whose content runs in one direction only correlates into a ridge: no
  /// curvature along it, a large variance there. Where H is not positive definite each
  /// axis is taken alone, and an axis without curvature gets kNoCurvatureVariance.
  PeakCovariance shiftCovariance(const PhaseNoise& ref, const PhaseNoise& cur,
                                 double noise_energy, const CorrelationPeak& peak) const;

  /// Correlation peak of two whitened bands. The integer peak is searched within
  /// |shift0| <= reach0 and |shift1| <= reach1 (input samples; a reach beyond n/2 searches
  /// everything, with wrap-around; reach0 is capped at the constructor's max_reach0), then
  /// refined by a 3-point Gaussian fit per axis (parabolic where a value is not positive).
  /// Allocation-free.
  CorrelationPeak correlate(const Complex* ref, const Complex* cur, double reach0, double reach1);

  /// As correlate(), searching |shift0 - centre0| <= nearReach0() (the centre rounded to a
  /// whole surface row) and |shift1| <= reach1: the cross-power spectrum is multiplied by
  /// the phase ramp that moves that centre row to row 0 (an exact cyclic shift of the
  /// surface), and only the rows the search and its sub-sample fit read are computed. A
  /// peak on the border of the band of rows (on_border) means the true peak may lie
  /// outside it. Without a planned band (nearReach0() 0) it searches every row, as
  /// correlate(). Allocation-free.
  CorrelationPeak correlateNear(const Complex* ref, const Complex* cur, double centre0,
                                double reach1);
  double nearReach0() const { return near_reach0_; }

 private:
  /// Input samples per surface row / column.
  double spacing0() const { return static_cast<double>(n0_) / s0_; }
  double spacing1() const { return static_cast<double>(n1_) / s1_; }
  /// band_ = ref * conj(cur) (both carry sqrt(W) / |F|), times exp(+i 2 pi k0 c / s0) on
  /// band row k0 when `shift_rows` c != 0 (the surface then peaks c rows earlier).
  void crossPower(const Complex* ref, const Complex* cur, int shift_rows);
  /// Peak of the surface the last inverse transform computed, searched within |d0| <=
  /// reach0 and |d1| <= reach1 (surface samples), reported `offset_rows` rows further.
  CorrelationPeak peak(double reach0, double reach1, int offset_rows) const;

  int n0_, n1_, s0_, s1_;
  int band_cols_;             ///< s1/2 + 1
  double max_reach0_;         ///< cap on correlate()'s reach0, input samples
  double near_reach0_;        ///< correlateNear()'s reach, input samples (0: not planned)
  FftwArray<float> sqrt_w2_;  ///< sqrt(W) twice per band bin (re, im lanes); 0 on the band's Nyquist row/column
  double weight_sum_ = 0.0;   ///< sum of W over the full (Hermitian) band = ideal peak height
  double noise_sigma_ = 0.0;  ///< std of the surface for random phases / weight_sum_
  /// PhaseNoise's weights, separable as W is: per band column m^2 W1^2 times 1, w1, w1^2
  /// (3 planes of band_cols_), per band row W0^2 times w0^2, w0, 1 (3 planes of s0_); 0 on
  /// the Nyquist row and column.
  FftwArray<float> noise_cols_, noise_rows_;
  FftwArray<Complex> band_;   ///< cross-power spectrum, the c2r input
  FftwArray<float> surface_;  ///< s0 x s1 correlation surface
  FftPlan inverse_;
  FftPlan near_;                   ///< correlateNear()'s inverse transform (rows around 0)
  FftwArray<Complex> unit_roots_;  ///< exp(+i 2 pi j / s0), j < s0 (correlateNear()'s ramp)
};

/// Smallest even size >= n whose only prime factors are 2, 3, 5, 7 (fast for FFTW).
int fastFftSize(int n);

}  // namespace omnipose::registration
