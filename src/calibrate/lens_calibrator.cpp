#include "omnipose/calibrate/lens_calibrator.hpp"
#include "omnipose/calibrate/ring_checks.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <sstream>
#include <stdexcept>

#include "common/format.hpp"
#include "omnipose/pipeline.hpp"
#include "omnipose/unwrapper.hpp"

namespace omnipose::calibrate {
namespace {

constexpr double kPi = std::numbers::pi;

using omnipose::detail::format;

std::string stackedNote(int stacked, double first, const char* way, double min_ratio) {
  if (stacked == 0) return "";
  return format("; the strongest edge at %.2f px is followed %s by %d more concentric "
                "lens-body edge(s) (coherent across the rays: median dP/dr at least %.0f %% of the "
                "first), so the ring starts at the last one",
                first, way, stacked, 100.0 * min_ratio);
}


}  // namespace

std::vector<std::string> LensCalibratorOptions::validate() const {
  std::vector<std::string> p;
  for (const auto& d : detector.validate()) p.push_back("detector." + d);
  if (radius_inner && !(*radius_inner >= 0)) p.push_back("radius_inner: must be >= 0");
  if (radius_outer && !(*radius_outer > 0)) p.push_back("radius_outer: must be > 0");
  if (radius_inner && radius_outer && !(*radius_outer > *radius_inner))
    p.push_back("radius_outer: must be greater than radius_inner");
  if (margin && !(*margin >= 0)) p.push_back("margin: must be >= 0 px");
  if (width && *width < 16) p.push_back("width: must be >= 16");
  if (height && *height < 4) p.push_back("height: must be >= 4");
  if (horizon_radius && !(*horizon_radius > 0)) p.push_back("horizon_radius: must be > 0");
  if (radial_scale && !(*radial_scale > 0)) p.push_back("radial_scale: must be > 0");
  if (forward_angle_deg && forward_point)
    p.push_back("forward_angle_deg: give either a forward angle or a forward point, not both");
  if (!std::isfinite(forward_column) || forward_column < 0)
    p.push_back("forward_column: must be >= 0");
  return p;
}

PanoramaProposal proposePanorama(double r_in, double r_out, OuterEdge outer_edge,
                                 std::optional<int> width, std::optional<int> height,
                                 std::optional<double> horizon_radius,
                                 std::optional<double> radial_scale) {
  PanoramaProposal p;
  // W from the outer circumference: one column per pixel of arc at r_out.
  p.width = width ? *width : static_cast<int>(std::lround(2.0 * kPi * r_out));
  p.horizon_radius = horizon_radius ? *horizon_radius : 0.5 * (r_in + r_out);
  // Square at the horizon: a row spans (r_out - r_in) / H px = gamma = 2 pi / W radians of
  // elevation there, i.e. (r_out - r_in) / (H s) = 2 pi / W; isotropic donut: s = r_h.
  p.radial_scale = radial_scale ? *radial_scale : p.horizon_radius;
  p.height = height ? *height
                    : std::max(4, static_cast<int>(std::lround(p.width * (r_out - r_in) /
                                                               (2.0 * kPi * p.radial_scale))));
  // Row of r_h under the linear radius -> row map of DESIGN.md section 6.
  const double step = (r_out - r_in) / p.height;
  p.horizon_row = outer_edge == OuterEdge::kTop ? (r_out - p.horizon_radius) / step - 0.5
                                                : (p.horizon_radius - r_in) / step - 0.5;
  return p;
}

std::vector<PairMotion> replayPairs(std::span<const cv::Mat> frames, const Calibration& cal) {
  std::vector<PairMotion> out;
  if (frames.size() < 2) return out;
  PipelineOptions po;
  po.registration.window = std::min(po.registration.window, cal.panorama.height);
  Pipeline pipeline(cal, po);
  Unwrapper unwrapper(cal, {});
  cv::Mat prev = unwrapper.makePanorama(), cur = unwrapper.makePanorama();
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const auto r = pipeline.process(frames[k]);
    const bool unwrapped = static_cast<bool>(unwrapper.unwrap(frames[k], cur));
    if (k > 0) {
      PairMotion m;
      m.from = static_cast<int>(k - 1);
      m.to = static_cast<int>(k);
      if (!r) {
        m.error = std::string(r.error().message());
      } else if (!r->has_motion) {
        m.error = "no motion estimate";
      } else {
        m.ok = r->estimate.status != FitStatus::kLost;
        if (!m.ok) m.error = std::string("fit status ") + toString(r->estimate.status);
        m.omega_deg = r->estimate.omega * 180.0 / kPi;
        m.tau_norm = r->tau_norm;
        m.windows_used = r->estimate.windows_used;
        m.windows_total = r->estimate.windows_total;
        m.residual_px = r->estimate.residual_rms_px;
      }
      if (unwrapped)
        if (const auto s = columnShift(prev, cur))
          m.column_shift_deg = s->du * 360.0 / cal.panorama.width;
      out.push_back(m);
    }
    std::swap(prev, cur);
  }
  return out;
}

namespace {

void addNote(LensCalibrationResult& res, std::string key, std::string value, std::string how) {
  res.provenance.push_back({std::move(key), std::move(value), std::move(how)});
}

/// Valid options, and frames that are all there and of one size; throws std::invalid_argument.
void checkInputs(std::span<const cv::Mat> frames, const LensCalibratorOptions& o) {
  if (const auto problems = o.validate(); !problems.empty()) {
    std::string msg = "invalid calibration options:";
    for (const auto& p : problems) msg += "\n  " + p;
    throw std::invalid_argument(msg);
  }
  if (frames.empty()) throw std::invalid_argument("no frames given");
  const cv::Size size = frames.front().size();
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (frames[k].empty()) throw std::invalid_argument(format("frame %zu is empty", k));
    if (frames[k].size() != size)
      throw std::invalid_argument(format("frame %zu is %dx%d, frame 0 is %dx%d", k,
                                         frames[k].cols, frames[k].rows, size.width,
                                         size.height));
  }

}

/// The ring per frame and its median (res.detections, detection_errors, ring), through the
/// quality gates (ring_checks.hpp): right or refuse.
void measureRing(std::span<const cv::Mat> frames, const LensCalibratorOptions& o,
                 LensCalibrationResult& res) {
  const bool need_detection = !(o.center && o.radius_inner && o.radius_outer);
  RingDetectorOptions dopt = o.detector;
  if (o.center) dopt.fixed_center = o.center;
  if (o.radius_inner) dopt.inner_guess = *o.radius_inner;
  if (o.radius_outer) dopt.outer_guess = *o.radius_outer;
  {
    MultiRingDetection multi = detectRings(frames, dopt);
    res.detections = std::move(multi.detections);
    res.detection_errors = std::move(multi.errors);
    res.ring = multi.estimate;
  }
  if (need_detection && !res.ring) {
    std::string why;
    for (std::size_t k = 0; k < res.detection_errors.size(); ++k)
      why += format("\n  frame %zu: %s", k, res.detection_errors[k].c_str());
    throw std::runtime_error(
        "no ring found in any frame; give --center-guess and/or --inner-guess/--outer-guess, or "
        "fix the values by hand with --center, --radius-inner, --radius-outer:" + why);
  }
  // Quality gates: right or refuse (ring_checks.hpp).
  if (res.ring && !(o.radius_inner && o.radius_outer)) {
    const RingCheck check = checkRing(frames, *res.ring, res.detections);
    if (!check.refusals.empty()) {
      std::string why = "refusing to calibrate: the ring found is not trustworthy:";
      for (const auto& r : check.refusals) why += "\n  " + r;
      throw std::runtime_error(why);
    }
    for (const auto& n : check.notes) {
      if (n.rfind("ring checked", 0) == 0) addNote(res, "ring check", "passed", n);
      else res.warnings.push_back(n);
    }
  }

}

enum class Edge { kInner, kOuter };

/// The used radius at the ring's inner or outer edge, with its note: given (--radius-inner,
/// --radius-outer), or the measured edge moved into the ring by the safety margin (given by
/// --margin, or 1 px for the bilinear footprint + 2 x the edge blur, std). Needs res.ring
/// when not given.
double usedRadius(const LensCalibratorOptions& o, Edge edge, const std::string& frames_note,
                  LensCalibrationResult& res) {
  const bool inner = edge == Edge::kInner;
  const char* key = inner ? "omni.radius_inner" : "omni.radius_outer";
  if (const std::optional<double>& given = inner ? o.radius_inner : o.radius_outer) {
    addNote(res, key, format("%.2f", *given),
            inner ? "given (--radius-inner)" : "given (--radius-outer)");
    return *given;
  }
  struct Measured {
    double radius, spread, blur, first;
    int stacked;
  };
  const RingEstimate& ring = *res.ring;
  const Measured m = inner ? Measured{ring.radius_inner, ring.inner_spread, ring.edge_width_inner,
                                      ring.first_inner, ring.stacked_inner}
                           : Measured{ring.radius_outer, ring.outer_spread, ring.edge_width_outer,
                                      ring.first_outer, ring.stacked_outer};
  const double margin = o.margin ? *o.margin : 1.0 + 2.0 * m.blur;
  (inner ? res.margin_inner : res.margin_outer) = margin;
  const double radius = inner ? m.radius + margin : m.radius - margin;
  addNote(res, key, format("%.2f", radius),
          format("measured: %s at %.2f px (median over %s, spread %.2f px%s) %c safety margin "
                 "%.2f px (%s)",
                 inner ? "inner edge (end of the dark centre / camera reflection)"
                       : "outer edge (start of the lens body)",
                 m.radius, frames_note.c_str(), m.spread,
                 stackedNote(m.stacked, m.first, inner ? "outward" : "inward",
                             o.detector.stack_min_contrast)
                     .c_str(),
                 inner ? '+' : '-', margin,
                 o.margin ? "--margin" : format("1 px + 2 x edge blur %.2f px", m.blur).c_str()));
  return radius;
}

/// The centre and the used radii (given, or measured less the safety margins); a warning
/// when the outer circle leaves the image. Throws when the used ring is empty.
void setCentreAndRadii(std::span<const cv::Mat> frames, const LensCalibratorOptions& o,
                       LensCalibrationResult& res) {
  auto& lens = res.calibration.omni;
  const cv::Size size = frames.front().size();
  const std::string frames_note =
      res.ring ? format("%d of %zu frames", res.ring->frames, frames.size()) : std::string();
  if (o.center) {
    lens.center_x = o.center->x();
    lens.center_y = o.center->y();
    addNote(res, "omni.center", format("[%.2f, %.2f]", lens.center_x, lens.center_y), "given (--center)");
  } else {
    lens.center_x = res.ring->center.x();
    lens.center_y = res.ring->center.y();
    addNote(res, "omni.center", format("[%.2f, %.2f]", lens.center_x, lens.center_y),
         format("measured: concentric circle fit to the inner and outer ring edges, median over "
                "%s (largest deviation of a frame %.2f px)",
                frames_note.c_str(), res.ring->center_spread));
  }

  lens.radius_inner = usedRadius(o, Edge::kInner, frames_note, res);
  lens.radius_outer = usedRadius(o, Edge::kOuter, frames_note, res);
  // Part of the used ring outside the image gives black panorama pixels: say so.
  {
    int outside = 0;
    constexpr int kRays = 720;
    for (int i = 0; i < kRays; ++i) {
      const double a = 2.0 * kPi * i / kRays;
      const double x = lens.center_x + lens.radius_outer * std::cos(a);
      const double y = lens.center_y + lens.radius_outer * std::sin(a);
      outside += x < 0 || y < 0 || x > size.width - 1 || y > size.height - 1;
    }
    if (outside > 0)
      res.warnings.push_back(format(
          "%.0f %% of the outer circle lies outside the image: those panorama pixels are black "
          "(the pipeline sees no texture there)", 100.0 * outside / kRays));
  }
  if (!(lens.radius_outer > lens.radius_inner + 4.0))
    throw std::runtime_error(format("the used ring is empty: radius_inner %.1f, radius_outer %.1f",
                                    lens.radius_inner, lens.radius_outer));

}

void setOuterEdge(std::span<const cv::Mat> frames, const LensCalibratorOptions& o,
                  LensCalibrationResult& res) {
  auto& lens = res.calibration.omni;
  // The vertical appearance cue.
  if (o.outer_edge) {
    lens.outer_edge = *o.outer_edge;
    addNote(res, "omni.outer_edge", toString(lens.outer_edge), "given (--outer-edge)");
  } else {
    res.outer_edge = outerEdgeFromAppearance(frames, lens, o.up_cue, o.default_outer_edge);
    lens.outer_edge = res.outer_edge->edge;
    addNote(res, "omni.outer_edge", toString(lens.outer_edge),
         (res.outer_edge->decisive ? "measured: " : "default: ") + res.outer_edge->how);
  }

}

void setPanorama(const LensCalibratorOptions& o, LensCalibrationResult& res) {
  auto& cal = res.calibration;
  auto& lens = cal.omni;
  const PanoramaProposal pp = proposePanorama(lens.radius_inner, lens.radius_outer,
                                              lens.outer_edge, o.width, o.height,
                                              o.horizon_radius, o.radial_scale);
  cal.panorama.width = pp.width;
  cal.panorama.height = pp.height;
  cal.panorama.horizon_row = o.horizon_row ? *o.horizon_row : pp.horizon_row;
  cal.panorama.forward_column = o.forward_column;
  addNote(res, "panorama.width", std::to_string(pp.width),
       o.width ? "given (--width)"
               : format("proposed: 2 pi r_out = %.1f (one column per pixel of the outer circumference)",
                        2.0 * kPi * lens.radius_outer));
  const double exact_h =
      pp.width * (lens.radius_outer - lens.radius_inner) / (2.0 * kPi * pp.radial_scale);
  addNote(res, "panorama.height", std::to_string(pp.height),
       o.height         ? std::string("given (--height)")
       : o.radial_scale ? format("proposed: square pixels at the horizon radius r_h = %.1f px with "
                                 "the given radial scale %.1f px/rad: W (r_out - r_in) / (2 pi s) "
                                 "= %.1f", pp.horizon_radius, pp.radial_scale, exact_h)
                        : format("proposed: square pixels at the horizon radius r_h = %.1f px, "
                                 "taking the donut as locally isotropic there (exact for a "
                                 "conformal mirror, an assumption otherwise; give "
                                 "--radial-scale from a lens model): W (r_out - r_in) / (2 pi r_h) "
                                 "= %.1f", pp.horizon_radius, exact_h));
  addNote(res, "panorama.horizon_row", format("%.2f", cal.panorama.horizon_row),
       o.horizon_row      ? "given (--horizon-row)"
       : o.horizon_radius ? format("row of the given horizon radius %.1f px", *o.horizon_radius)
                          : std::string("assumed: the middle of the ring (no mirror model; "
                                        "fix with --horizon-radius or --horizon-row)"));
  addNote(res, "panorama.forward_column", format("%.2f", cal.panorama.forward_column),
       o.forward_column != 0.0 ? "given (--forward-column)" : "default: 0");

}

void setAzimuthZero(const LensCalibratorOptions& o, LensCalibrationResult& res) {
  auto& lens = res.calibration.omni;
  if (o.forward_angle_deg) {
    lens.azimuth_zero_deg = *o.forward_angle_deg;
    addNote(res, "omni.azimuth_zero_deg", format("%.2f", lens.azimuth_zero_deg),
         "given (--forward-angle): image angle of the robot's +x axis");
  } else if (o.forward_point) {
    lens.azimuth_zero_deg = imageAngleDeg(lens, *o.forward_point);
    addNote(res, "omni.azimuth_zero_deg", format("%.2f", lens.azimuth_zero_deg),
         format("given (--forward-point %.1f,%.1f): image angle of that point about the centre",
                o.forward_point->x(), o.forward_point->y()));
  } else {
    lens.azimuth_zero_deg = 0.0;
    addNote(res, "omni.azimuth_zero_deg", "0.00",
         "default: 0 (image +x axis is forward); set it with --forward-angle DEG or "
         "--forward-point X,Y");
  }

}

/// Given, measured from a turn-left sequence, or assumed from the outer edge.
void setAzimuthDirection(std::span<const cv::Mat> frames, const LensCalibratorOptions& o,
                         LensCalibrationResult& res) {
  auto& cal = res.calibration;
  auto& lens = cal.omni;
  if (o.direction) {
    lens.azimuth_direction = *o.direction;
    addNote(res, "omni.azimuth_direction", toString(lens.azimuth_direction), "given (--direction)");
  } else if (o.turn_left && frames.size() >= 2) {
    res.direction = directionFromTurnLeft(frames, cal);
    if (res.direction->decisive) {
      lens.azimuth_direction = res.direction->direction;
      addNote(res, "omni.azimuth_direction", toString(lens.azimuth_direction),
           "measured: " + res.direction->how);
    } else {
      lens.azimuth_direction = assumedDirection(lens.outer_edge);
      addNote(res, "omni.azimuth_direction", toString(lens.azimuth_direction),
           format("assumed %s from outer_edge %s for an unmirrored camera image, because the %s",
                  toString(lens.azimuth_direction), toString(lens.outer_edge), res.direction->how.c_str()));
    }
  } else {
    if (o.turn_left)
      res.warnings.push_back("--turn-left needs at least 2 frames; the direction is assumed");
    lens.azimuth_direction = assumedDirection(lens.outer_edge);
    addNote(res, "omni.azimuth_direction", toString(lens.azimuth_direction),
         format("assumed: %s for outer_edge %s and an unmirrored camera image (camera looking %s "
                "at the mirror); not measured: pass a turn-left sequence with --turn-left",
                toString(lens.azimuth_direction), toString(lens.outer_edge),
                lens.outer_edge == OuterEdge::kTop ? "up" : "down"));
  }

}

}  // namespace

LensCalibrationResult calibrateLens(std::span<const cv::Mat> frames,
                                    const LensCalibratorOptions& o) {
  checkInputs(frames, o);
  const cv::Size size = frames.front().size();
  LensCalibrationResult res;
  auto& cal = res.calibration;
  cal.omni.image_width = size.width;
  cal.omni.image_height = size.height;
  addNote(res, "omni.image_width/height", format("%d x %d", size.width, size.height),
          format("measured: size of the %zu frame(s)", frames.size()));
  measureRing(frames, o, res);
  setCentreAndRadii(frames, o, res);
  setOuterEdge(frames, o, res);
  setPanorama(o, res);
  setAzimuthZero(o, res);
  setAzimuthDirection(frames, o, res);

  if (const auto problems = cal.validate(); !problems.empty()) {
    std::string msg = "the resulting calibration is invalid:";
    for (const auto& p : problems) msg += "\n  " + p;
    throw std::runtime_error(msg);
  }

  if (o.replay && frames.size() >= 2) res.motions = replayPairs(frames, cal);
  return res;
}

std::string LensCalibrationResult::yaml() const {
  std::ostringstream out;
  out << "# Written by omnipose-calibrate. How each value was determined:\n";
  for (const auto& p : provenance) out << "#   " << p.key << " = " << p.value << ": " << p.how << "\n";
  out << calibration.toYaml();
  return out.str();
}

std::string LensCalibrationResult::report() const {
  std::ostringstream out;
  out << "Circles per frame (edges before the safety margin):\n";
  std::size_t d = 0;
  for (std::size_t k = 0; k < detection_errors.size(); ++k) {
    if (!detection_errors[k].empty()) {
      out << format("  frame %zu: not detected: %s\n", k, detection_errors[k].c_str());
      continue;
    }
    const auto& r = detections[d++];
    out << format(
        "  frame %zu: centre (%.2f, %.2f)  r_inner %.2f  r_outer %.2f  rms %.2f px | inner "
        "circle (%.2f, %.2f) r %.2f, %.0f%% of rays, blur %.2f px, polarity %+d | outer circle "
        "(%.2f, %.2f) r %.2f, %.0f%% of rays, blur %.2f px, polarity %+d\n",
        k, r.center.x(), r.center.y(), r.radius_inner, r.radius_outer, r.rms,
        r.inner.circle.center.x(), r.inner.circle.center.y(), r.inner.circle.radius,
        100.0 * r.inner.inlier_fraction, r.inner.width, r.inner.polarity,
        r.outer.circle.center.x(), r.outer.circle.center.y(), r.outer.circle.radius,
        100.0 * r.outer.inlier_fraction, r.outer.width, r.outer.polarity);
    if (r.inner.stacked > 0)
      out << format("    inner: the strongest edge is at %.2f px; moved outward past %d stacked "
                    "lens-body edge(s)\n", r.inner.first_radius, r.inner.stacked);
    if (r.outer.stacked > 0)
      out << format("    outer: the strongest edge is at %.2f px; moved inward past %d stacked "
                    "lens-body edge(s)\n", r.outer.first_radius, r.outer.stacked);
  }
  out << "Calibration values and how each was determined:\n";
  for (const auto& p : provenance)
    out << format("  %-24s %-16s %s\n", p.key.c_str(), p.value.c_str(), p.how.c_str());
  for (const auto& w : warnings) out << "Warning: " << w << "\n";
  if (!motions.empty()) {
    out << "Replay through the Pipeline with this calibration (roll x, pitch y, yaw z):\n";
    for (const auto& m : motions) {
      if (m.ok)
        out << format(
            "  frame %d -> %d: roll %+.2f  pitch %+.2f  yaw %+.2f deg  |tau| %.3f  windows "
            "%d/%d  residual %.2f px  (whole-panorama column shift %+.2f deg)\n",
            m.from, m.to, m.omega_deg.x(), m.omega_deg.y(), m.omega_deg.z(), m.tau_norm,
            m.windows_used, m.windows_total, m.residual_px, m.column_shift_deg);
      else
        out << format("  frame %d -> %d: no estimate (%s); whole-panorama column shift %+.2f deg\n",
                      m.from, m.to, m.error.c_str(), m.column_shift_deg);
    }
  }
  return out.str();
}

std::vector<std::string> LensCalibrationResult::summaryLines() const {
  std::vector<std::string> lines;
  const auto& o = calibration.omni;
  const auto& p = calibration.panorama;
  lines.push_back(format("centre (%.2f, %.2f)  used radii %.2f .. %.2f px  (edges %.2f .. %.2f)",
                         o.center_x, o.center_y, o.radius_inner, o.radius_outer,
                         ring ? ring->radius_inner : o.radius_inner,
                         ring ? ring->radius_outer : o.radius_outer));
  lines.push_back(format("azimuth_zero %.1f deg  direction %s  outer_edge %s  panorama %d x %d  "
                         "horizon row %.1f",
                         o.azimuth_zero_deg, toString(o.azimuth_direction), toString(o.outer_edge),
                         p.width, p.height, p.horizon_row));
  for (const auto& pr : provenance) {
    if (pr.key == "omni.azimuth_direction" || pr.key == "omni.outer_edge" ||
        pr.key == "omni.azimuth_zero_deg") {
      std::string how = pr.how;
      if (how.size() > 150) how = how.substr(0, 147) + "...";
      lines.push_back(pr.key.substr(5) + ": " + how);
    }
  }
  for (const auto& w : warnings) lines.push_back("warning: " + w);
  for (const auto& m : motions)
    if (m.ok)
      lines.push_back(format("replay %d->%d: roll %+.2f pitch %+.2f yaw %+.2f deg", m.from, m.to,
                             m.omega_deg.x(), m.omega_deg.y(), m.omega_deg.z()));
  return lines;
}

}  // namespace omnipose::calibrate
