#pragma once
/// \file window_motion.hpp
/// What the window registration measures for one panorama window and the motion fit
/// consumes, and the window taper both of them depend on (one definition, so the fit's
/// window attenuation kappa always describes the taper the registration applied).

#include <algorithm>
#include <cmath>
#include <numbers>

namespace omnipose {

/// Motion of one window between the reference and the current panorama.
/// Sign convention (DESIGN.md sections 2/3): content at (u, v) of the current window appears
/// at (u + du, v + dv) in the previous (reference) window; the in-window map from current to
/// reference coordinates is s * [[1, phi], [-phi, 1]].
/// A confidence is the height of the phase-correlation peak (1 for identical content) above
/// the highest peak that random phases would produce over the searched region, rescaled to
/// [0, 1]: ~0 for unrelated content, > 0.9 for a clean match. It is a weight, not a
/// probability.
struct WindowMotion {
  double center_u = 0.0;    ///< window centre column, pixels, reduced modulo W into [0, W)
  double du = 0.0;          ///< shift along u, pixels (see above for the sign)
  double dv = 0.0;          ///< shift along v, pixels
  double rotation = 0.0;    ///< in-window rotation phi, radians (counter-clockwise on screen);
                            ///< 0 when rs_confidence is 0
  double scale = 1.0;       ///< in-window scale s; 1 when rs_confidence is 0
  double confidence = 0.0;  ///< translation peak quality in [0, 1]; 0 = no usable peak
  double rs_confidence = 0.0;  ///< rotation/scale peak quality in [0, 1]; 0 = not measured
                               ///< (estimate_rotation_scale off), no usable peak, or the
                               ///< peak on the border of the prior (true value outside it)
  /// Covariance of (du, dv), pixels^2, for panorama noise of unit variance (grey levels^2):
  /// multiply by the noise variance for the absolute figure (the motion fit estimates that
  /// factor from its residuals). It comes from how precisely each spectral frequency of the
  /// two windows is known (PhaseCorrelator::shiftCovariance, src/registration): a window
  /// whose content runs in one direction only (a door frame, blinds) knows its shift
  /// across it and not along it. 0 when not measured (confidence 0, or
  /// WindowRegistration::Options::shift_covariance off).
  double var_du = 0.0;
  double var_dv = 0.0;
  double cov_du_dv = 0.0;
  /// Share of the window's taper weight whose pixels its own motion does not explain
  /// (content moving on its own: a person walking by), in [0, 1]; the refinement pass's
  /// windows only (PipelineOptions::moving_content), 0 otherwise. confidence and
  /// rs_confidence are already lowered by it (0 from 0.06 on). In the windows a pass
  /// reports (OdometryResult::windows), 1 for a window its fit's ring consensus left out
  /// (MotionFit::judgedMoving: it moved as a whole, as no static scene does).
  double moving_fraction = 0.0;
  /// The window's vertical scale alone, s_v: current row y (about the window centre) appears
  /// at s_v y in the reference, from the window's column profiles (each row's taper-weighted
  /// mean) in the two panoramas; the expansion the model's ln s describes, without the
  /// horizontal one that a change of depth across the window adds (src/pipeline/
  /// vertical_scale.hpp). Measured by the pipeline's passes when the fit uses it
  /// (MotionFit::Options::vertical_scale), for windows with a rotation/scale peak; 1 otherwise.
  double vertical_scale = 1.0;
  /// Standard deviation of ln s_v from its fit's residuals; 0 = not measured (or the fit
  /// failed), and vertical_scale is then 1.
  double vertical_scale_sigma = 0.0;
  bool valid = false;       ///< false: window has no texture / no peak (confidence below
                            ///< min_confidence); ignore it. du, dv = 0 for a textureless window
  bool masked = false;      ///< mostly masked (setValidity): not measured, valid = false
};

/// The separable window taper of the registration, sample j of a window of `length`
/// samples: the Hann window h(j) = 0.5 - 0.5 cos(2 pi (j + 0.5) / length), positive and
/// symmetric about the window centre (length - 1) / 2. Requires 0 <= j < length.
inline double windowTaper(int j, int length) {
  return 0.5 - 0.5 * std::cos(2.0 * std::numbers::pi * (j + 0.5) / length);
}

/// How much more a least-squares fit over windows of `length` samples placed every `step`
/// samples varies than it would if the windows' errors were independent: the sum over
/// lags j of sum_x h(x)^2 h(x + j step)^2 / sum_x h(x)^4 (h = windowTaper; 1 when the windows
/// do not overlap). Errors caused by pixels that neighbouring windows share (noise, the
/// resampling) are correlated that much, and the fit's covariance, which treats windows as
/// independent, is multiplied by it (2.83 at the paper's L 110, d 20). Requires length,
/// step > 0.
inline double windowOverlapFactor(int length, int step) {
  double overlap = 0.0, self = 0.0;
  for (int x = 0; x < length; ++x) {
    const double h = windowTaper(x, length);
    self += h * h * h * h;
  }
  for (int lag = -(length / step) * step; lag < length; lag += step) {
    for (int x = std::max(0, -lag); x < length && x + lag < length; ++x) {
      const double a = windowTaper(x, length), b = windowTaper(x + lag, length);
      overlap += a * a * b * b;
    }
  }
  return overlap / self;
}

}  // namespace omnipose
