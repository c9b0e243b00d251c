#pragma once
/// \file motion_model.hpp
/// The first-order motion model of DESIGN.md section 3: how a camera motion (omega, tau)
/// moves, rotates and scales a panorama window centred at azimuth theta.
///
///   du * gamma = omega_z + tau_y cos(theta) - tau_x sin(theta)          (Eq. 3b, linear form)
///   dv * gamma = -omega_x sin(theta) + omega_y cos(theta) - tau_z       (Eq. 3a, linear form)
///   phi        = omega_x cos(theta) + omega_y sin(theta)                (in-window rotation)
///   ln s       = -(tau_x cos(theta) + tau_y sin(theta))                 (in-window scale)
///
/// omega is the rotation vector of R (P_{k-1} = R P_k + t), tau = t / rho with rho the
/// horizontal scene distance. A window spans an azimuth range, and iFMI reports the
/// average motion inside it: the sinusoidal terms are therefore multiplied by the window
/// attenuation kappa = E_w[cos(delta)] over the window's azimuth offsets delta, weighted by
/// the window taper (kappa = 1 for an infinitely narrow window).
/// ln s is the vertical expansion; where the scene's depth changes along the ring the
/// horizontal one differs, which the fit adds with per-window depth
/// (MotionFit::Options::scale_depth_gradient, DESIGN.md section 3).

#include <Eigen/Core>

namespace omnipose {

/// One window's motion as the model predicts it.
struct ModelMotion {
  double du_rad = 0.0;     ///< du * gamma, radians
  double dv_rad = 0.0;     ///< dv * gamma, radians
  double rotation = 0.0;   ///< phi, radians
  double log_scale = 0.0;  ///< ln s
};

/// Kappa for a window of `window_px` columns under the registration's taper (windowTaper(),
/// window_motion.hpp) at `gamma` radians per column.
double windowAttenuation(int window_px, double gamma);

/// Rows of the linear system A x = b for x = (omega_x, omega_y, omega_z, tau_x, tau_y,
/// tau_z), one per measured quantity of a window at azimuth theta.
struct ModelRows {
  Eigen::Matrix<double, 1, 6> du;         ///< for b = du * gamma
  Eigen::Matrix<double, 1, 6> dv;         ///< for b = dv * gamma
  Eigen::Matrix<double, 1, 6> rotation;   ///< for b = phi
  Eigen::Matrix<double, 1, 6> log_scale;  ///< for b = ln s
};
ModelRows modelRows(double theta, double kappa = 1.0);

/// Predicted motion of the window at azimuth theta for x = (omega, tau).
ModelMotion predictMotion(const Eigen::Matrix<double, 6, 1>& x, double theta, double kappa = 1.0);

/// The shift (du, dv), in panorama pixels, that x = (omega, tau) predicts for the window centred
/// on column `center_u` of a panorama of `gamma` radians per column with +x at column
/// `forward_column`: predictMotion() at theta = gamma * (center_u - forward_column), over gamma.
/// A measured window's du - shift.x() is its residual against the fit (fit_diagnostics_t).
Eigen::Vector2d predictWindowShiftPx(const Eigen::Matrix<double, 6, 1>& x, double center_u,
                                     double forward_column, double gamma, double kappa = 1.0);

}  // namespace omnipose
