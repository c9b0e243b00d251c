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
///
/// Realtime: construction reserves the workspace for `max_windows`; fit() allocates
/// nothing and never throws.

#include <Eigen/Core>
#include <span>
#include <string>
#include <vector>

#include "omnipose/window_registration.hpp"

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
  int windows_total = 0;
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
  struct Options {
    double huber_delta_px = 2.0;    ///< pseudo-Huber delta, pixels (paper: 2)
    int median = 5;                 ///< median pre-filter length in windows (odd, 0/1 = off)
    double median_reject_px = 6.0;  ///< pre-filter rejection threshold, pixels
    int max_iterations = 20;        ///< IRLS iterations
    double tolerance = 1e-9;        ///< IRLS stops when |dx| (radians) falls below this
    bool use_rotation_scale = true; ///< add the in-window rotation/scale equations
    double inlier_sigmas = 3.0;     ///< final pass keeps |r| < this many robust sigmas
    double min_window_fraction = 0.3;  ///< fewer valid windows than this fraction: degraded
    double max_residual_px = 1.5;      ///< larger inlier RMS: degraded
    double max_condition = 1e6;        ///< larger normal-matrix condition number: lost
    int max_windows = 512;             ///< workspace size

    /// Empty when valid, else a message naming the bad field.
    std::string validate() const;
  };

  /// `gamma`: radians per panorama column; `window_px`: window size L (for the window
  /// attenuation). Throws std::invalid_argument on invalid options.
  MotionFit(const Options& options, double gamma, int window_px);

  /// Fits the model to `windows`; a window's azimuth is theta = gamma * (center_u - forward_column).
  /// `windows.size()` must not exceed options().max_windows (else status kLost).
  MotionEstimate fit(std::span<const WindowMotion> windows, double forward_column);

  const Options& options() const { return options_; }

 private:
  struct Row {
    Eigen::Matrix<double, 1, 6> a;
    double b = 0.0;      ///< measurement in model units (radians or ln s)
    double scale = 1.0;  ///< pixels per model unit (1/gamma for du/dv), for the loss
    double prior_weight = 1.0;  ///< confidence / noise weight
    double weight = 1.0;        ///< current IRLS weight
    int kind = 0;               ///< 0 du, 1 dv, 2 rotation, 3 log scale
  };
  int buildTranslationRows(std::span<const WindowMotion> windows, double forward_column);
  Eigen::Matrix<double, 6, 1> irls(int n_rows, int& iterations, bool& ok);
  double robustSigma(int kind, const Eigen::Matrix<double, 6, 1>& x, int n_rows);

  Options options_;
  double gamma_;
  double kappa_;
  std::vector<Row> rows_;
  std::vector<double> scratch_;
  std::vector<unsigned char> keep_;
};

}  // namespace omnipose
