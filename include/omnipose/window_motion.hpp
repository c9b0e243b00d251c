#pragma once
/// \file window_motion.hpp
/// What the window registration measures for one panorama window and the motion fit
/// consumes, and the window taper both of them depend on (one definition, so the fit's
/// window attenuation kappa always describes the taper the registration applied).

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

}  // namespace omnipose
