#include "result_convert.hpp"

#include <nanobind/eigen/dense.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>

#include <cstdio>

#include "bindings.hpp"
#include "omnipose/motion_model.hpp"

namespace nb = nanobind;

namespace omnipose::python {

namespace {

WindowArrays windowArrays(const OdometryResult& r, const WindowGeometry& g) {
  const auto n = static_cast<Eigen::Index>(r.windows.size());
  WindowArrays a;
  for (Eigen::VectorXd* v : {&a.center_u, &a.du, &a.dv, &a.rotation, &a.scale, &a.confidence,
                             &a.model_du, &a.model_dv, &a.weight, &a.moving_fraction})
    v->resize(n);
  a.valid.resize(n);
  a.masked.resize(n);
  a.refined = r.windows_refined;
  a.gamma = g.gamma;
  a.forward_column = g.forward_column;
  for (Eigen::Index k = 0; k < n; ++k) {
    const WindowMotion& w = r.windows[static_cast<std::size_t>(k)];
    a.center_u[k] = w.center_u;
    a.du[k] = w.du;
    a.dv[k] = w.dv;
    a.rotation[k] = w.rotation;
    a.scale[k] = w.scale;
    a.confidence[k] = w.confidence;
    a.valid[k] = w.valid;
    a.masked[k] = w.masked;
    a.weight[k] = static_cast<std::size_t>(k) < r.window_weights.size()
                      ? r.window_weights[static_cast<std::size_t>(k)]
                      : 0.0;
    a.moving_fraction[k] = w.moving_fraction;
    const Eigen::Vector2d model =
        predictWindowShiftPx(r.window_model, w.center_u, g.forward_column, g.gamma, g.kappa);
    a.model_du[k] = model.x();
    a.model_dv[k] = model.y();
  }
  return a;
}

}  // namespace

WindowGeometry windowGeometry(const Calibration& calibration, const Odometry& odometry) {
  return {calibration.panorama.gamma(), calibration.panorama.forward_column,
          odometry.windowAttenuation()};
}

FrameResult toFrameResult(const Expected<OdometryResult>& result, double time_s,
                          const WindowGeometry& geometry) {
  FrameResult f;
  f.time_s = time_s;
  if (!result) {
    f.error = std::string(toString(result.error().code()));
    f.message = std::string(result.error().message());
    return f;
  }
  const OdometryResult& r = *result;
  const MotionEstimate& e = r.relative.estimate;
  f.state = toString(r.state);
  f.status = toString(e.status);
  f.has_motion = r.relative.has_motion;
  f.rotation = r.relative.rotation;
  f.rotation_vector = e.omega;
  f.tau = e.tau;
  f.translation_direction = r.relative.translation_direction;
  f.tau_norm = r.relative.tau_norm;
  f.covariance = e.covariance;
  f.residual_rms_px = e.residual_rms_px;
  f.windows_used = e.windows_used;
  f.windows_total = e.windows_total;
  f.pose = r.pose.matrix();
  f.map_pose = r.map_pose.matrix();
  f.loop_closed = r.loop_closed;
  f.loop_place_sequence = r.loop_place_sequence;
  f.places = r.places;
  f.segment = r.segment;
  f.sequence = r.sequence;
  f.reference_sequence = r.reference_sequence;
  f.keyframe_sequence = r.keyframe_sequence;
  f.frames_since_keyframe = r.frames_since_keyframe;
  f.timing = r.relative.timing;
  f.windows = windowArrays(r, geometry);
  return f;
}

namespace {

std::string describe(const FrameResult& f) {
  char buf[256];
  if (f.error) {
    std::snprintf(buf, sizeof(buf), "FrameResult(sequence=%lld, error='%s')",
                  static_cast<long long>(f.sequence), f.error->c_str());
  } else {
    std::snprintf(buf, sizeof(buf),
                  "FrameResult(sequence=%lld, state='%s', status='%s', rotation_vector=[%.6g, "
                  "%.6g, %.6g], tau_norm=%.6g)",
                  static_cast<long long>(f.sequence), f.state->c_str(), f.status.c_str(),
                  f.rotation_vector.x(), f.rotation_vector.y(), f.rotation_vector.z(), f.tau_norm);
  }
  return buf;
}

}  // namespace

void bindResult(nb::module_& m) {
  using W = WindowArrays;
  nb::class_<W>(m, "Windows",
                "The windows of the pass that made a frame's estimate, one entry per window (empty "
                "without an estimate): what the daemon's fit_diagnostics_t carries. Shifts in "
                "panorama pixels (content at u of the current window appears at u + du in the "
                "reference), rotation in radians, scale as a factor; model_du/model_dv: the shift "
                "the fitted motion predicts at the window (du - model_du is its residual). "
                "Read-only arrays.")
      .def_ro("center_u", &W::center_u, "Window centre column, (n,).")
      .def_ro("du", &W::du, "Measured shift along u, pixels, (n,).")
      .def_ro("dv", &W::dv, "Measured shift along v, pixels, (n,).")
      .def_ro("rotation", &W::rotation, "Measured in-window rotation, radians, (n,).")
      .def_ro("scale", &W::scale, "Measured in-window scale factor, (n,).")
      .def_ro("confidence", &W::confidence, "Translation peak quality 0..1, (n,).")
      .def_ro("valid", &W::valid, "Usable window, bool (n,).")
      .def_ro("masked", &W::masked, "Mostly covered by the lens mask, not measured, bool (n,).")
      .def_ro("model_du", &W::model_du, "Fitted motion's du at the window, pixels, (n,).")
      .def_ro("model_dv", &W::model_dv, "Fitted motion's dv at the window, pixels, (n,).")
      .def_ro("weight", &W::weight,
              "How much the window weighed in the fit, relative to the heaviest (1); 0 = left "
              "out (beyond the inlier threshold, invalid, masked), (n,).")
      .def_ro("moving_fraction", &W::moving_fraction,
              "Share of the window's pixels its own motion does not explain (a person walking "
              "by), 0..1; refinement pass only (moving_content), else 0; 1 for a window the "
              "ring consensus (ring_consensus) left out, (n,).")
      .def_ro("refined", &W::refined,
              "The refinement pass's windows (the current panorama de-rotated by the estimate "
              "before it), else the first pass's.")
      .def_ro("gamma", &W::gamma, "Radians per panorama column.")
      .def_ro("forward_column", &W::forward_column,
              "The column of +x: a window's azimuth is gamma * (center_u - forward_column).")
      .def("__len__", [](const W& w) { return w.du.size(); });
  using R = FrameResult;
  nb::class_<R>(m, "FrameResult",
                "One frame's outcome of Odometry.process(). Camera frame: x forward, y left, z "
                "up. The relative motion is frame `sequence` in frame `reference_sequence`: "
                "P_ref = R P + t, t known up to scale (tau = t / rho, rho the scene's distance). "
                "Arrays are read-only float64 arrays over the result's memory (copy to change them).")
      .def_ro("time_s", &R::time_s, "The frame's capture time as given, seconds.")
      .def_prop_ro("ok", [](const R& r) { return !r.error; },
                   "False when the frame was rejected (error says why); the odometry's state is "
                   "then as before the frame and the next one is treated as after a gap.")
      .def_ro("error", &R::error,
              "None, or why the frame was rejected: 'bad_frame' (black, wrong size or type) or "
              "'implausible' (a glitch: torn, repeated, flipped or foreign frame).")
      .def_ro("message", &R::message, "The rejection's message ('' when ok).")
      .def_ro("state", &R::state,
              "How the pose was obtained: 'start' (segment start: no motion, pose held), "
              "'tracked', 'bridged' (after a gap, found again against the keyframe), 'lost' (new "
              "segment), 'gyro' (the gap bridged by the gyro); None after an error.")
      .def_ro("status", &R::status, "The fit's status: 'ok', 'degraded' or 'lost'.")
      .def_ro("has_motion", &R::has_motion, "False at a segment start (no pair yet).")
      .def_ro("rotation", &R::rotation, "R, 3 x 3: exp([omega]x).")
      .def_ro("rotation_vector", &R::rotation_vector, "omega, (3,), radians.")
      .def_ro("tau", &R::tau, "tau = t / rho, (3,), in scene distances.")
      .def_ro("translation_direction", &R::translation_direction,
              "t / |t|, (3,); zeros when |tau| = 0.")
      .def_ro("tau_norm", &R::tau_norm, "|tau| = |t| / rho.")
      .def_ro("covariance", &R::covariance,
              "6 x 6 covariance of (omega, tau) as fitted (radians, scene distances), in the "
              "keyframe's frame; infinite entries where unknown (a gyro bridge's translation).")
      .def_ro("residual_rms_px", &R::residual_rms_px, "RMS of the inlier residuals, pixels.")
      .def_ro("windows_used", &R::windows_used, "Windows in the final fit.")
      .def_ro("windows_total", &R::windows_total, "Windows given to the fit, masked ones included.")
      .def_ro("pose", &R::pose,
              "Chained pose, 4 x 4 (camera to segment origin; positions in scene distances).")
      .def_ro("map_pose", &R::map_pose,
              "The pose in the map frame, 4 x 4: `pose` corrected by the loop closures so far "
              "(jumps when a loop closes; equal to `pose` before the first closure).")
      .def_ro("loop_closed", &R::loop_closed, "This frame closed a loop: map_pose jumped.")
      .def_ro("loop_place_sequence", &R::loop_place_sequence,
              "The place a closing frame was matched with (its frame's sequence), else -1.")
      .def_ro("places", &R::places, "Places in the odometry's memory.")
      .def_ro("segment", &R::segment, "0 for the first segment, +1 at each new one.")
      .def_ro("sequence", &R::sequence, "This frame's number.")
      .def_ro("reference_sequence", &R::reference_sequence,
              "The frame the motion is relative to; -1 at a segment start.")
      .def_ro("keyframe_sequence", &R::keyframe_sequence,
              "The keyframe the pose was anchored to (reference_sequence when none was).")
      .def_ro("frames_since_keyframe", &R::frames_since_keyframe, "Frames since that keyframe.")
      .def_ro("windows", &R::windows, "The windows of the pass that made the estimate (Windows).")
      .def_prop_ro("seconds", [](const R& r) { return r.timing.total; },
                   "Wall time of the pipeline for this frame, seconds.")
      .def_prop_ro(
          "timing",
          [](const R& r) {
            nb::dict d;
            d["unwrap"] = r.timing.unwrap;
            d["registration"] = r.timing.registration;
            d["fit"] = r.timing.fit;
            d["refine"] = r.timing.refine;
            d["total"] = r.timing.total;
            return d;
          },
          "Wall time of each stage, seconds: unwrap, registration, fit, refine, total.")
      .def("__repr__", &describe);
}

}  // namespace omnipose::python
