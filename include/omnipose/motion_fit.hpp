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
/// translation lambda_k stays at 1 and nothing changes. The log-scale rows then also carry
/// the horizontal expansion that the depth's change across a window adds
/// (Options::scale_depth_gradient).
///
/// Realtime: construction reserves the workspace for `max_windows` windows (the
/// registration's window count); fit() allocates nothing and never throws.

#include <Eigen/Core>
#include <memory>
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
    /// A prior for rooms (daemon.yaml `pipeline.plane_depth_prior`; on by default). Each
    /// window's relative inverse depth is expected on the vertical plane through its nearest
    /// kept neighbours' (within two windows on each side; a wall's inverse depth along the
    /// ring is A cos(theta) + B sin(theta), so any wall satisfies it exactly, corners and
    /// objects in front of a wall do not), spread 0.15, taken at the neighbours' depths of
    /// each Gauss-Newton step; the pull towards 1 widens to 4 (depth_prior_sigma is not
    /// used); and the in-window scale equations weigh 0.01 of what their scatter says (a
    /// window's log-polar scale mixes its horizontal and vertical expansion in a proportion
    /// its texture sets, an error its scatter does not show). The depths of the windows near
    /// the direction of travel, whose du hardly depends on them, then come from their
    /// neighbours instead of from the scale and the pull: without it (false, the fit before
    /// 2026-11-30) the heading of a robot driving in a room turned one way or the other with
    /// the walls' texture (docs/results/DRIFT_POOL.md). The covariance counts the prior with
    /// its coupling of neighbouring depths.
    bool plane_depth_prior = true;
    /// Leave out, before the fit, the windows that no static scene explains
    /// (daemon.yaml `pipeline.ring_consensus`; on by default): du's sinusoid fitted with
    /// one depth for every window by least median of squares over the ring, a window out
    /// when no relative inverse depth in [0, 8] brings its du within 4 robust sigmas of it
    /// (at least the ring's own noise, kept within [0.1, 0.5] px), times the ring's median
    /// confidence over its own where its peak is weaker; not tested within 45 deg of the
    /// direction of travel, or within 10 deg when the consensus's direction agrees with the
    /// previous fit's (ring_consensus.hpp). Without it per_window_depth lets a translation
    /// explain people walking across a third of the ring as near objects, and the
    /// background between them as far, and the yaw follows (docs/results/PEOPLE.md, its
    /// "consensus off" column); where nobody walks it moves the per-pair error by a few
    /// percent (docs/results/ANALYSIS.md, "The ring consensus by default"). false: people
    /// walking by can bend the yaw.
    bool ring_consensus = true;
    /// With per_window_depth: how much of the horizontal expansion that a change of depth
    /// across a window adds the measured in-window scale carries. A window on a wall seen
    /// at an angle expands vertically by -lambda (tau_x cos + tau_y sin), as the model's
    /// ln s says, and horizontally by that plus dlambda/dtheta D (D = tau_y cos - tau_x sin,
    /// the translation part of its du per unit inverse depth); the log-polar scale of such
    /// an anisotropic expansion is a mix of the two. The fit subtracts
    /// scale_depth_gradient * dlambda/dtheta * D from ln s, dlambda/dtheta taken from the
    /// neighbouring windows' depths. 0.5 (default): the isotropic mix, a texture without a
    /// preferred direction; 0: the model without the term, which reads the expansion as
    /// depth and lets a robot driving along a wall turn (docs/results/ANALYSIS.md). With
    /// plane_depth_prior the scale weighs 0.01 and the term matters little. [0, 1].
    double scale_depth_gradient = 0.5;
    /// With use_rotation_scale: the in-window scale equations take each window's vertical
    /// scale (WindowMotion::vertical_scale, measured by the pipeline's passes) instead of its
    /// log-polar one (daemon.yaml `pipeline.vertical_scale`). A translation's vertical
    /// expansion is exactly the model's ln s, so scale_depth_gradient is not used; each
    /// window's equation weighs (median sigma / its sigma)^2, within [0.05, 4], of what the
    /// equations' scatter says, its sigma WindowMotion::vertical_scale_sigma and the median
    /// over the pass's scale equations; a window without a vertical scale
    /// (vertical_scale_sigma 0) has no scale equation, its rotation equation stays.
    bool vertical_scale = false;
    /// With use_rotation_scale: the in-window rotation equations' error under translation,
    /// per unit of |tau| (the expansion a translation gives a window at the mean depth),
    /// added in quadrature to their scatter to make their sigma. The log-polar correlation
    /// measures a window's rotation exactly when the window turns and scales as a whole;
    /// translation deforms it otherwise (a wall seen at an angle expands it more across
    /// than up, the floor in its lower rows more than the wall above), and the correlation
    /// reads part of that as a rotation whose sign the window's texture sets: the same
    /// pair after pair of a straight drive, which it rolled and pitched. Turning in place
    /// leaves the equations their full weight. 1 (default): an error as large as the
    /// deformation; 0: their scatter alone, which lets a straight drive roll
    /// (docs/results/ANALYSIS.md). [0, 100].
    double rotation_deformation = 1.0;
    /// Each window's du and dv equations weighted by their own variance
    /// (WindowMotion::var_du, var_dv): the confidence divided by the variance over the
    /// pair's median window variance where that ratio is above 1, so a window that sees
    /// only vertical edges gives its du and hardly its dv; the loss and the inlier test
    /// read its residuals in units of its own standard deviation. Windows without
    /// variances (0) count as the median. Off by default: it lowers the rotation error of
    /// frame pairs, but the translation direction in a room and the chained drift get worse
    /// (docs/results/ANALYSIS.md). false: the confidence alone weighs both (the paper).
    bool window_covariance = false;
    /// How far the final pass shrinks tau towards 0 when the images hardly ask for it
    /// (daemon.yaml `pipeline.translation_shrinkage`). Turning in place, nothing needs a
    /// translation, yet a free tau and per-window depths take up part of whatever else
    /// moves (people walking by) and bend the rotation with it. tau becomes
    /// tau max(0, 1 - K / chi2), chi2 = tau^T C^-1 tau, C the covariance of tau times
    /// windowOverlapFactor() of the windows' size and spacing (the covariance the pipeline
    /// publishes), and the rotation is solved again from the final pass with that tau. The
    /// default K = 3 is the chi2 a tau of three degrees of freedom has on average when the
    /// camera does not move: the factor is the share of chi2 above what noise alone gives
    /// (an empirical-Bayes gain). On the people benchmark's straight drives chi2 is over 150
    /// and tau keeps at least 98 % of its length; a turn in place keeps little or none
    /// (docs/results/ANALYSIS.md). 0: tau as fitted (the fit before 2026-12-05). [0, 100].
    double translation_shrinkage = 3.0;
    /// The camera rides a ground robot (daemon.yaml `pipeline.planar_motion_deg`): between
    /// two frames it translates within this angle of its own horizontal plane (camera z up:
    /// a robot drives along its floor, and a ramp tilts the camera with it). The fit then
    /// takes tau_z ~ N(0, sigma_z^2) as a prior, sigma_z = |tau| sin(angle) with |tau| from
    /// its first pass, and at least a twentieth of the shifts' noise, so that turning in
    /// place holds tau_z at 0: a free tau_z lets people walking by lend the fit a vertical
    /// translation that the per-window depths turn into rotation. The covariance includes
    /// the prior. 0: tau_z free (a hand-held camera, a drone, a robot that climbs steps).
    /// [0, 45] degrees.
    double planar_motion_deg = 10.0;

    /// Every problem, one message per bad field, each starting with the field's name
    /// ("median: 4 must be odd (or 0/1 = off)"); empty when valid.
    std::vector<std::string> validate() const;
  };

  /// `gamma`: radians per panorama column; `window_px`: window size L (for the window
  /// attenuation kappa); `max_windows`: most windows one fit() is given (the workspace is
  /// sized for it; WindowRegistration::windowCount()). Throws std::invalid_argument listing
  /// every invalid option or argument.
  MotionFit(const Options& options, double gamma, int window_px, int max_windows);

  /// Copies fit alike (the workspace is copied, allocating as construction does). A
  /// moved-from MotionFit may only be assigned to or destroyed.
  MotionFit(const MotionFit& other);
  MotionFit& operator=(const MotionFit& other);
  MotionFit(MotionFit&& other) noexcept;
  MotionFit& operator=(MotionFit&& other) noexcept;
  ~MotionFit();

  /// Fits the model to `windows`; a window's azimuth is theta = gamma * (center_u - forward_column).
  /// With Options::ring_consensus a fit depends on the ones before it: the consensus takes the
  /// direction of travel of the last fit (status kOk) whose translation moved the windows by
  /// more than half a pixel as its prior (a copy carries it).
  /// `windows.size()` must not exceed maxWindows() (else status kLost). `row_scale`
  /// (optional, one per window, else status kLost): the model's du and dv for window k are
  /// row_scale[k].du and .dv times the motion's (a window whose measurement spans a longer
  /// time than the motion fitted: a rolling shutter, DESIGN.md section 3); empty = 1.
  struct RowScale {
    double du = 1.0, dv = 1.0;
  };
  MotionEstimate fit(std::span<const WindowMotion> windows, double forward_column,
                     std::span<const RowScale> row_scale = {});

  const Options& options() const;
  /// Radians per panorama column.
  double gamma() const;
  /// The window attenuation kappa the model rows use (motion_model.hpp).
  double kappa() const;
  /// Relative inverse depth lambda_k (mean 1) of window k after the last fit(); 1 when the
  /// depths were not fitted (per_window_depth off, or a fit that stopped before its depth
  /// step) and before any fit. Requires 0 <= k < maxWindows().
  double inverseDepth(int k) const;
  /// How much window k weighed in the last fit()'s final pass: its du and dv rows' weights
  /// (confidence, noise) summed, over the heaviest window's, in [0, 1]; 0 for a window the
  /// final pass left out (beyond the inlier threshold, invalid, masked), for every window when
  /// the fit stopped before its final pass, and before any fit. Requires
  /// 0 <= k < maxWindows().
  double finalWeight(int k) const;
  /// Whether the ring consensus (Options::ring_consensus) left window k out of the last
  /// fit(): no static scene explains its du (a person walking by covers it). False with the
  /// consensus off, for a window it did not judge (invalid, dropped by the median filter,
  /// near the direction of travel) and before any fit. Requires 0 <= k < maxWindows().
  bool judgedMoving(int k) const;
  /// Most windows one fit() accepts.
  int maxWindows() const;

 private:
  struct Impl;  ///< the workspace and the fit's steps (src/fit/motion_fit.cpp)
  std::unique_ptr<Impl> impl_;
};

}  // namespace omnipose
