#pragma once
/// \file log_polar.hpp
/// Log-polar resampling of the high-passed magnitude spectrum of an n x n window (iFMI,
/// Buelow & Birk). Input: the r2c half plane, n rows (k_v) x (n/2 + 1) columns (k_u >= 0).
/// Output row a is the angle alpha_a = -pi/2 + a pi / n_theta of the frequency vector
/// (k_u, k_v) = rho (cos alpha, sin alpha); the half plane alpha in [-pi/2, pi/2) is the whole
/// spectrum since |F(-k)| = |F(k)|, so the output is periodic along rows. Output column b is
/// the radius rho_b = r_min (r_max / r_min)^(b / (n_r - 1)) (frequency bins).
///
/// Interpolation is a cubic B-spline (4 x 4 taps), not bilinear: bilinear interpolation
/// blurs by f (1 - f) (f = sub-bin position), a blur pattern fixed to the FFT grid that
/// pulls the rotation/scale estimates towards zero (0.35 deg and 0.6 % on 110 px windows);
/// the B-spline's blur does not depend on f (errors 0.09 deg, 0.2 %). The quadratic
/// B-spline cost accuracy beyond the 5 % allowed, and a table of the 16 weight products per
/// sample saved instructions but no time (docs/PERFORMANCE.md).
///
/// A rotation of the window content by phi (counter-clockwise on screen) and a scaling by s
/// shift the log-polar image by (-phi / angleStep(), -ln s / logRadiusStep()) samples
/// (see window_registration.cpp for the derivation).

#include <vector>

#include "registration/fft.hpp"

namespace omnipose::registration {

class LogPolarMap {
 public:
  /// n: FFT size of the window (even); 0 < r_min < r_max <= n/2 - 3, frequency bins.
  LogPolarMap(int n, int n_theta, int n_radius, double r_min, double r_max);

  int angles() const { return n_theta_; }
  int radii() const { return n_radius_; }
  /// Radians per output row.
  double angleStep() const { return angle_step_; }
  /// Natural-log units of radius per output column.
  double logRadiusStep() const { return log_radius_step_; }

  /// out (n_theta x n_radius) = taper(b) * (g(a, b) - mean_a g) / rms_a g, where g is the
  /// B-spline interpolation of H |F| and H = 1 - cos^2(pi |k| / n) is the high-pass
  /// emphasis filter (clamped to 1 beyond |k| = n/2). The per-radius normalisation removes
  /// the isotropic radial profile, which carries no rotation and would bias the scale
  /// towards 1; the taper removes the wrap-around edge along log-radius. Returns the
  /// energy sum out^2. Allocation-free.
  double resample(const Complex* spectrum, float* out);

 private:
  /// Fills grid_ with H |F| over the disk the taps read, mirrored for k_u < 0
  /// (|F(-k)| = |F(k)|).
  void fillGrid(const Complex* spectrum);

  int n_, n_theta_, n_radius_;
  double angle_step_, log_radius_step_;
  // Extended grid of H |F|: rows k_v in [-reach, reach], columns k_u in [-1, reach].
  int reach_;                      ///< largest |k| component a tap reads
  int grid_cols_;                  ///< reach + 2
  std::vector<float> grid_;        ///< (2 reach + 1) x grid_cols_
  std::vector<float> high_pass_;   ///< H per grid entry
  // Per output sample: grid offset of the first tap and the separable B-spline weights.
  std::vector<int> tap_offset_;
  std::vector<int> row_columns_;   ///< per grid row: 1 + the last column a tap reads (0: none)
  std::vector<float> weight_u_;    ///< 4 per sample; tap-major per four samples of a row
  std::vector<float> weight_v_;    ///< 4 per sample
  std::vector<float> taper_;       ///< per output column
  std::vector<float> column_mean_;   ///< scratch, per output column
  std::vector<float> column_gain_;   ///< scratch, per output column
};

}  // namespace omnipose::registration
