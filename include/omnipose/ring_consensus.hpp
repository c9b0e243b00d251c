#pragma once
// The motion most of the ring agrees on, and the windows that no static scene explains.
//
// The fit's model gives each window's horizontal shift as a sinusoid over its azimuth theta
// (motion_model.hpp):
//   du = a + lambda_k (b sin theta + c cos theta)      (a: yaw; b, c: tau_x, tau_y)
// with lambda_k > 0 the window's relative inverse depth. With a free lambda_k per window a
// translation can explain almost any pattern of du: people walking across a third of the
// ring become "near objects" of a translation that is not there, and the background between
// them "far" (docs/results/ANALYSIS.md, people). The consensus therefore fits the sinusoid
// with ONE depth for all windows (lambda_k = 1), by least median of squares over triples of
// windows spread around the ring (breakdown point 50 %: people may cover up to half of it),
// then refits on its inliers. A window is inconsistent when no inverse depth in
// [0, max_inverse_depth] brings its du within max(sigmas * robust sigma, floor) of the
// consensus: the robust sigma of those depth-absorbed residuals over the ring. With a free
// depth per window most of them are 0, and so is that sigma; the floor is then what judges:
// sigmas times the least-median fit's own robust sigma (one depth for every window), kept
// within [min_floor_px, floor_px]. Turning in place the ring agrees with one depth within
// its noise (a few hundredths of a pixel), and a window that a person covers in part, its
// shift pulled 0.2-0.6 px, stands out; driving past walls near and far, one depth misfits by
// their parallax and the floor stays at floor_px. The
// consensus's sinusoid is refitted on the windows within 2.5 of its robust sigmas, alternately
// with each window's depth, so that walls at different distances do not turn it. A window the
// translation explains with some depth (a wall close by while the robot drives) stays; a
// window that moves against a robot turning in place does not. A window whose phase-correlation
// peak is weaker than the ring's median peak has a less certain shift: its threshold is
// multiplied by the median confidence over its own, so the consensus leaves out the windows
// that disagree with it confidently (a person covering them) and leaves the weak ones (a
// plain wall's noisy shift, or a window the pipeline's moving-content check has already
// lowered) to the fit's weights. Near the translation's axis
// (within axis_half_width_deg, when the translation moves the windows by more than floor_px)
// a window's du says more about the axis's direction than about its depth, and the
// consensus's direction is not exact enough to judge it: there du is not tested. Beside a
// wall close by, one depth for every window misfits the near side's sharper crest, and the
// least-median axis can be some 30 deg off. When it agrees with the previous fit's axis
// (previous_axis_rad, within agreed_axis_half_width_deg; a robot's direction of travel in
// the camera's frame hardly changes from one frame to the next), the axis is known and du
// is tested from agreed_axis_half_width_deg of it: a person crossing in front of a driving
// robot, whom no depth explains, is left out.
//
// Windows overlap their neighbours (110 px wide, 20 px apart by default), so a person who
// covers one window covers part of the next, and pulls its du part of the way: below the
// threshold, yet its dv and du bend the fit. A window next to one left out is therefore left
// out when its residual exceeds neighbour_fraction of its own threshold (the hysteresis of
// Canny's edge linking: a strong flag, and weak ones joined to it). Where nobody walks a
// window left out is mostly a single one whose peak erred; its neighbours mostly agree with
// the ring, and stay.
//
// dv is not tested. Its sinusoid (roll, pitch and the vertical translation) takes a
// window's whole vertical shift, and beside a wall close by a slanted edge moving sideways
// shifts a window vertically too: in driving a dv test left out about one window per fit
// that no person was in (and its du with it), which moved a lap's heading by up to 1.2 deg,
// better in some rooms and worse in others, while on the people pool it helped one render
// of 35 (docs/results/ANALYSIS.md). The fit's robust weights take care of a window's dv.
#include <cstdint>
#include <limits>
#include <span>

namespace omnipose {

struct RingConsensusOptions {
  /// Threshold in robust sigmas of the absorbed residuals; the floor in those of the
  /// one-depth residuals.
  double sigmas = 4.0;
  double floor_px = 0.5;      ///< the floor's largest value, pixels (one depth misfits the ring)
  /// The floor's smallest value, pixels (the ring agrees within noise); above floor_px it is
  /// the floor.
  double min_floor_px = 0.1;
  double max_inverse_depth = 8.0;   ///< largest relative inverse depth a window may take
  double axis_half_width_deg = 45.0;  ///< du not tested this close to the translation's axis
  /// The translation's axis of the fit before, as the consensus's sinusoid gives it:
  /// atan2(c, b) of b sin theta + c cos theta (radians; either sign of the axis). NaN:
  /// unknown, and axis_half_width_deg holds.
  double previous_axis_rad = std::numeric_limits<double>::quiet_NaN();
  /// When the consensus's axis is within this of previous_axis_rad, du is not tested only
  /// this close to the axis (degrees).
  double agreed_axis_half_width_deg = 10.0;
  /// A window next around the ring to one left out (within 1.6 mean spacings of the samples'
  /// azimuths) is left out too when its residual exceeds this fraction of its threshold
  /// (hysteresis); 0: off. Neighbouring windows overlap, so a person who covers one covers
  /// part of the next, whose shift is pulled part of the way.
  double neighbour_fraction = 0.3;
};

/// One window as the consensus sees it: azimuth (radians), horizontal shift (pixels) and the
/// peak's confidence (WindowMotion::confidence; only its ratio to the other samples' counts).
/// A confidence that is not finite or not above 0 counts as the median.
struct RingSample {
  double theta = 0.0;
  double du_px = 0.0;
  double confidence = 1.0;
};

/// Sets inconsistent[k] = 1 for the samples no static scene explains and those beside them
/// (see above), 0 for the others, and returns how many were flagged. `work` must hold at
/// least 3 samples.size() doubles and `inconsistent` at least samples.size() flags (no
/// allocation). With fewer than 8 samples, a smaller buffer, or when no triple of windows is
/// well conditioned (all on one side of the ring), nothing is flagged.
int flagInconsistentWindows(std::span<const RingSample> samples,
                            const RingConsensusOptions& options, std::span<std::uint8_t> inconsistent,
                            std::span<double> work);

}  // namespace omnipose
