#pragma once
/// \file motion_fit.hpp
/// Robust fit of the linear motion model (motion_model.hpp) to the window motions of one
/// frame pair: the paper's two sinusoids, written in the basis {1, sin, cos}, so the fit is
/// a 6x6 weighted linear least-squares problem in x = (omega, tau) with no initial guess
/// and no local minima.
///
/// Steps: (1) median pre-filter: a window whose du or dv differs from the median of its
/// `median` circular neighbours by more than `median_reject_px` is dropped (values are not
/// replaced, so the sinusoids keep their amplitude); (2) iteratively reweighted least
/// squares with the pseudo-Huber loss delta * (sqrt(1 + (r/delta)^2) - 1) (weights
/// 1/sqrt(1 + (r/delta)^2)), times the window confidence; (3) optionally the in-window
/// rotation and scale equations join, each weighted by the inverse of its own robust noise
/// variance measured against the translation-only fit; (4) a final least-squares pass on
/// the inliers (|r| < inlier_sigmas robust sigmas) gives the estimate and its covariance.
/// With per_window_depth, between (3) and (4) each window's relative inverse depth
/// lambda_k (tau_k = lambda_k tau, prior N(1, depth_prior_sigma)) joins the unknowns: the
/// model becomes bilinear and is solved by Gauss-Newton with the lambda eliminated through
/// the Schur complement; the covariance is the marginal one of (omega, tau). Without
/// translation lambda_k stays at 1 and nothing changes.
///
/// Realtime: construction reserves the workspace for `max_windows` windows (the
/// registration's window count); fit() allocates nothing and never throws.

#include <Eigen/Core>
#include <span>
#include <string>
#include <vector>

#include "omnipose/window_motion.hpp"

namespace omnipose {

/// Quality of a fit, also the pose status published by the daemon.
enum class FitStatus {
  kOk,        ///< well conditioned, enough windows, small residual
  kDegraded,  ///< usable but few windows or a large residual: trust it less
  kLost,      ///< no unique solution (too few or degenerate windows): do not use
};
const char* toString(FitStatus status);

/// Result of one fit. Angles in radians, tau dimensionless (t / rho).
struct MotionEstimate {
  Eigen::Vector3d omega = Eigen::Vector3d::Zero();  ///< rotation vector of R
  Eigen::Vector3d tau = Eigen::Vector3d::Zero();    ///< t / rho
  Eigen::Matrix<double, 6, 6> covariance = Eigen::Matrix<double, 6, 6>::Zero();  ///< of (omega, tau)
  double residual_rms_px = 0.0;  ///< RMS of the inlier du/dv residuals, pixels
  int windows_used = 0;          ///< windows contributing to the final pass
  int windows_total = 0;         ///< windows given to the fit, masked ones included
  int windows_masked = 0;        ///< windows not measured because mostly masked
  int iterations = 0;
  FitStatus status = FitStatus::kLost;

  Eigen::Matrix<double, 6, 1> vector() const {
    Eigen::Matrix<double, 6, 1> x;
    x << omega, tau;
    return x;
  }
};

class MotionFit {
 public:
  /// Fewest measured windows the fit solves from (their du and dv rows over-determine the
  /// six unknowns); with fewer, every estimate is lost.
  static constexpr int kMinWindows = 4;

  struct Options {
    double huber_delta_px = 2.0;    ///< pseudo-Huber delta, pixels (paper: 2)
    int median = 5;                 ///< median pre-filter length in windows (odd, 0/1 = off)
    double median_reject_px = 6.0;  ///< pre-filter rejection threshold, pixels
    int max_iterations = 20;        ///< IRLS iterations
    double tolerance = 1e-9;        ///< IRLS stops when |dx| (radians) falls below this
    bool use_rotation_scale = true; ///< add the in-window rotation/scale equations
    double inlier_sigmas = 3.0;     ///< final pass keeps |r| < this many robust sigmas
    double min_window_fraction = 0.3;  ///< fewer valid windows than this fraction of the
                                       ///< unmasked ones: degraded
    double max_residual_px = 1.5;      ///< larger inlier RMS: degraded
    double max_condition = 1e6;        ///< larger normal-matrix condition number: lost
    /// Per-window inverse depth: every window gets its own rho_mean/rho_k (mean 1), so a
    /// room whose walls are at different distances does not turn translation into
    /// rotation. Solved jointly with (omega, tau) by Gauss-Newton (Schur complement).
    bool per_window_depth = true;
    double depth_prior_sigma = 0.5;  ///< prior spread of the relative inverse depth around 1

    /// Every problem, one message per bad field, each starting with the field's name
    /// ("median: 4 must be odd (or 0/1 = off)"); empty when valid.
    std::vector<std::string> validate() const;
  };

  /// `gamma`: radians per panorama column; `window_px`: window size L (for the window
  /// attenuation kappa); `max_windows`: most windows one fit() is given (the workspace is
  /// sized for it; WindowRegistration::windowCount()). Throws std::invalid_argument listing
  /// every invalid option or argument.
  MotionFit(const Options& options, double gamma, int window_px, int max_windows);

  /// Fits the model to `windows`; a window's azimuth is theta = gamma * (center_u - forward_column).
  /// `windows.size()` must not exceed maxWindows() (else status kLost).
  MotionEstimate fit(std::span<const WindowMotion> windows, double forward_column);

  const Options& options() const { return options_; }
  /// Radians per panorama column.
  double gamma() const { return gamma_; }
  /// The window attenuation kappa the model rows use (motion_model.hpp).
  double kappa() const { return kappa_; }
  /// Relative inverse depth lambda_k (mean 1) of window k after the last fit(); 1 when the
  /// depths were not fitted (per_window_depth off, or a fit that stopped before its depth
  /// step) and before any fit. Requires 0 <= k < maxWindows().
  double inverseDepth(int k) const { return depth_[k]; }
  /// Most windows one fit() accepts.
  int maxWindows() const { return static_cast<int>(keep_.size()); }

 private:
  struct Row {
    Eigen::Matrix<double, 1, 6> a;   ///< design row; translation columns times depth_[window]
    Eigen::Matrix<double, 1, 6> a0;  ///< design row for uniform depth
    double b = 0.0;      ///< measurement in model units (radians or ln s)
    double scale = 1.0;  ///< pixels per model unit (1/gamma for du/dv), for the loss
    double prior_weight = 1.0;  ///< confidence / noise weight
    double weight = 1.0;        ///< current IRLS weight
    int kind = 0;               ///< 0 du, 1 dv, 2 rotation, 3 log scale
    int window = 0;             ///< index of the window the row belongs to
    double leverage = 0.0;      ///< share of the row absorbed by its window's inverse depth
  };
  int buildTranslationRows(std::span<const WindowMotion> windows, double forward_column);
  Eigen::Matrix<double, 6, 1> irls(int n_rows, int& iterations, bool& ok);
  double robustSigma(int kind, const Eigen::Matrix<double, 6, 1>& x, int n_rows);
  /// Noise of the shift rows in radians (the larger of du and dv, floored at 0.01 px).
  double shiftSigma(const Eigen::Matrix<double, 6, 1>& x, int n_rows);
  /// Leverage of every row on its window's inverse depth (0 without per-window depth).
  void computeLeverage(std::span<const WindowMotion> windows, int n_rows,
                       const Eigen::Matrix<double, 6, 1>& x);
  /// |residual| in pixels divided by sqrt(1 - leverage).
  double standardizedResidualPx(int i, const Eigen::Matrix<double, 6, 1>& x) const;
  /// Per-window inverse depth: sets the prior weight from the noise and runs
  /// depthGaussNewton (twice, the second time with the depth model's own noise); returns x.
  Eigen::Matrix<double, 6, 1> fitDepth(std::span<const WindowMotion> windows, int n_rows,
                                       Eigen::Matrix<double, 6, 1> x, int& iterations);
  /// Joint Gauss-Newton in (omega, tau) and the per-window inverse depths (in depth_),
  /// backtracked on depthCost(); sigma: the shift rows' noise (radians), which sets when a
  /// step is negligible.
  Eigen::Matrix<double, 6, 1> depthGaussNewton(std::span<const WindowMotion> windows,
                                               int n_rows, Eigen::Matrix<double, 6, 1> x,
                                               double sigma, int& iterations);
  /// The robust objective depthGaussNewton() lowers, at x and the current depth_.
  double depthCost(std::span<const WindowMotion> windows, int n_rows,
                   const Eigen::Matrix<double, 6, 1>& x) const;

  Options options_;
  double gamma_;
  double kappa_;
  std::vector<Row> rows_;
  std::vector<double> scratch_;
  std::vector<unsigned char> keep_;
  std::vector<double> depth_;  ///< relative inverse depth per window (mean 1)
  std::vector<Eigen::Matrix<double, 6, 1>> depth_xl_;  ///< N_x,lambda_k columns (covariance)
  double depth_prior_weight_ = 0.0;  ///< weight of the lambda_k = 1 prior (0: depth not fitted)
};

}  // namespace omnipose
