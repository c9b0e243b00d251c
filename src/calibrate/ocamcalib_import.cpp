#include "omnipose/calibrate/ocamcalib_import.hpp"
#include "omnipose/calibrate/orientation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <stdexcept>

#include "common/format.hpp"

namespace omnipose::calibrate {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

using omnipose::detail::format;

}  // namespace

std::string placePanoramaInRing(Calibration& c, int width, int height,
                                std::optional<double> horizon_row, double edge_margin_deg,
                                const std::string& origin, std::vector<std::string>& notes) {
  // The cylinder rows must lie inside the ring's elevations (minus a margin).
  PanoramaGeometry& p = c.panorama;
  p.width = width;
  p.height = height;
  const auto [e_in, e_out] = c.ringElevations();
  const double lo = std::min(e_in, e_out) + edge_margin_deg * kDeg;
  const double hi = std::max(e_in, e_out) - edge_margin_deg * kDeg;
  const double gamma = p.gamma();
  const double h_lo = std::tan(lo), h_hi = std::tan(hi);  // cylinder heights of the ring
  const double span_rows = (h_hi - h_lo) / gamma;         // rows that fit
  if (!(span_rows >= p.height)) {
    throw std::runtime_error(
        origin + format(": a %d x %d panorama does not fit into the ring's elevations "
                        "%.1f..%.1f deg",
                        p.width, p.height, lo / kDeg, hi / kDeg) +
        format(" (%.0f rows at this width): lower --height or --width", std::floor(span_rows)));
  }
  if (horizon_row) {
    p.horizon_row = *horizon_row;
    notes.push_back(format("horizon row %.2f as given", p.horizon_row));
  } else {
    // Row v spans heights gamma (v_h - v -+ 0.5); rows -0.5 .. H - 0.5 must stay in [h_lo, h_hi].
    const double centred = 0.5 * p.height - 0.5;
    const double v_min = h_lo / gamma + p.height - 0.5;  // lowest v_h keeping the bottom row in
    const double v_max = h_hi / gamma - 0.5;             // highest v_h keeping the top row in
    p.horizon_row = std::clamp(centred, v_min, v_max);
    notes.push_back(
        format("horizon row %.2f: panorama elevations %.1f..%.1f deg", p.horizon_row,
               std::atan(gamma * (p.horizon_row - p.height + 0.5)) / kDeg,
               std::atan(gamma * (p.horizon_row + 0.5)) / kDeg) +
        format(" inside the ring's %.1f..%.1f deg", lo / kDeg, hi / kDeg) +
        (p.horizon_row == centred ? " (horizon in the middle)" : " (horizon moved off the middle to fit)"));
  }
  return notes.back();
}

void finishModelCalibration(Calibration& c, const ModelImportOptions& options,
                            std::span<const cv::Mat> frames, const std::string& origin,
                            std::vector<std::string>& notes) {
  OmniLens& lens = c.omni;
  placePanoramaInRing(c, options.width, options.height, options.horizon_row,
                      options.edge_margin_deg, origin, notes);
  // Azimuth (measured on that panorama when there is a turn-left sequence).
  lens.azimuth_zero_deg = options.forward_angle_deg;
  lens.azimuth_direction = options.direction.value_or(AzimuthDirection::kCcw);
  std::string direction_how = options.direction ? "as given" : "ccw ASSUMED (a mirror seen from "
                                                               "below; check with --turn-left)";
  if (options.turn_left && !options.direction) {
    if (frames.size() < 2)
      throw std::runtime_error("--turn-left needs at least 2 frames of the robot turning left");
    const DirectionResult d = directionFromTurnLeft(frames, c);
    if (!d.decisive)
      throw std::runtime_error("--turn-left: the frames do not show a clear turn (" + d.how +
                               "); try frames further apart or give --direction");
    lens.azimuth_direction = d.direction;
    direction_how = std::string(toString(d.direction)) +
                    " measured from the turn-left sequence (" + d.how + ")";
  }
  notes.push_back(format("forward (+x) at image angle %.1f deg, azimuth direction ",
                         lens.azimuth_zero_deg) + direction_how);
  if (const auto problems = c.validate(); !problems.empty()) {
    std::string what = origin + ": the proposed calibration is not usable:";
    for (const auto& q : problems) what += "\n  " + q;
    throw std::runtime_error(what);
  }
}

ModelImport importOcamCalib(const std::filesystem::path& file,
                                const ModelImportOptions& options,
                                std::span<const cv::Mat> frames) {
  ModelImport out;
  Calibration& c = out.calibration;
  OmniLens& lens = c.omni;
  lens.model = LensModelKind::kOcamCalib;
  lens.ocamcalib_file = file.filename().string();
  lens.ocamcalib = OcamCalibModel::load(file);  // throws naming the file and line
  const OcamCalibModel& m = *lens.ocamcalib;
  lens.image_width = m.width;
  lens.image_height = m.height;
  lens.center_x = m.yc;
  lens.center_y = m.xc;
  out.notes.push_back(format("centre (%.2f, %.2f) px and frame %d x %d from the file", m.yc,
                             m.xc, m.width, m.height) +
                      (m.crop_left || m.crop_right
                           ? format(" (calibrated on a crop: %d px left, %d px right)",
                                    m.crop_left, m.crop_right)
                           : std::string()));

  // The used ring.
  if (options.radius_inner && options.radius_outer) {
    lens.radius_inner = *options.radius_inner;
    lens.radius_outer = *options.radius_outer;
    out.notes.push_back(format("ring %.1f..%.1f px as given", lens.radius_inner, lens.radius_outer));
  } else if (m.roi_min_radius && m.roi_max_radius) {
    lens.radius_inner = options.radius_inner.value_or(*m.roi_min_radius);
    lens.radius_outer = options.radius_outer.value_or(*m.roi_max_radius);
    out.notes.push_back(format("ring %.1f..%.1f px from the file's ROI line", lens.radius_inner,
                               lens.radius_outer));
  } else {
    throw std::runtime_error(file.string() +
                             ": has no ROI line: give the used ring with --radius-inner and "
                             "--radius-outer (pixels from the centre)");
  }
  out.notes.push_back(format("invpol agrees with ss to %.3f px over the ring (world2cam is "
                             "refined on ss)", m.invpolMaxErrorPx(lens.radius_inner, lens.radius_outer)));

  finishModelCalibration(c, options, frames, file.string(), out.notes);
  return out;
}

}  // namespace omnipose::calibrate
