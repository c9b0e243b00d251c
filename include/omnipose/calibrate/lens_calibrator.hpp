#pragma once
/// \file lens_calibrator.hpp
/// The whole lens calibration behind one entry point: ring detection on
/// every frame (median over frames), safety margins, the proposed panorama size, the
/// orientation values, and a note for every value saying how it was determined.
///
/// Values and how they are found (each can be fixed by hand in LensCalibrator::Options):
///  - centre, edge radii: RingDetector per frame, median over frames.
///  - radius_inner / radius_outer: the edges moved into the ring by a safety margin, so
///    the bilinear unwrap never mixes in the lens body: by default 1 px + 2 x the measured
///    edge blur (std), per edge.
///  - panorama.width W = round(2 pi r_out) (one panorama column per pixel of the outer
///    circumference).
///  - panorama.height H: square pixels at the horizon row. Without a mirror model the
///    local scale of the donut is taken as isotropic at the horizon radius r_h (exact for a
///    conformal, e.g. para-catadioptric, mirror; an assumption otherwise): one row spans
///    (r_out - r_in) / H px radially and one column 2 pi r_h / W px of arc, so
///    H = round(W (r_out - r_in) / (2 pi r_h)). r_h defaults to the middle of the ring
///    (horizon_row = H/2 - 0.5). With a lens model, give r_h and the radial scale s at the
///    horizon (image pixels per radian of elevation, dr/dphi): H = W (r_out - r_in) / (2 pi s).
///    Example (the OCamCalib mirror in shared/data): f(rho) = 0 at r_h = 443.2 px and
///    s = 308.1 px/rad, so s = 0.70 r_h: the isotropic guess gives a 26 % too small H there.
///  - azimuth_direction: from a turn-left sequence (orientation.hpp); otherwise assumed
///    from outer_edge for an unmirrored camera image (and said so).
///  - outer_edge: from the vertical appearance cue (orientation.hpp), else the default.
///  - azimuth_zero_deg: a forward angle or image point the user gives; else 0 (said so).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "omnipose/calibrate/orientation.hpp"
#include "omnipose/calibrate/ring_detector.hpp"
#include "omnipose/calibration.hpp"

namespace omnipose::calibrate {

/// One value of the calibration and how it was determined.
struct Provenance {
  std::string key;    ///< e.g. "omni.center"
  std::string value;  ///< as written to the YAML
  std::string how;    ///< "measured: ...", "given: ...", "default: ...", "assumed: ..."
};

/// Motion between consecutive frames measured with the Pipeline under the calibration
/// (a sanity check: a turn in place should be mostly yaw).
struct PairMotion {
  int from = 0, to = 1;
  bool ok = false;
  std::string error;               ///< when !ok
  Eigen::Vector3d omega_deg = Eigen::Vector3d::Zero();  ///< roll (x), pitch (y), yaw (z), degrees
  double tau_norm = 0.0;
  int windows_used = 0, windows_total = 0;
  double residual_px = 0.0;
  double column_shift_deg = 0.0;   ///< the whole-panorama column shift du * gamma, degrees
};

struct LensCalibratorOptions {
  RingDetectorOptions detector;

  // Fixed by hand (each replaces the measured value).
  std::optional<Eigen::Vector2d> center;  ///< pixels; the radii are then fitted about it
  std::optional<double> radius_inner;     ///< used radii, pixels (no margin applied)
  std::optional<double> radius_outer;
  std::optional<double> margin;           ///< safety margin for both edges, pixels; default auto
  std::optional<int> width;               ///< panorama W
  std::optional<int> height;              ///< panorama H
  std::optional<double> horizon_radius;   ///< r_h in the omni image, pixels
  std::optional<double> radial_scale;     ///< dr/dphi at the horizon, pixels per radian
  std::optional<double> horizon_row;      ///< v_h (overrides horizon_radius for the row)
  double forward_column = 0.0;            ///< u0
  std::optional<double> forward_angle_deg;        ///< image angle of +x, degrees
  std::optional<Eigen::Vector2d> forward_point;   ///< an image point straight ahead (+x)
  std::optional<AzimuthDirection> direction;
  std::optional<OuterEdge> outer_edge;

  /// The frames, in order, are a sequence in which the robot turns left in place.
  bool turn_left = false;
  UpCue up_cue = UpCue::kBright;
  OuterEdge default_outer_edge = OuterEdge::kTop;
  /// Replay consecutive frames through the Pipeline after calibrating (PairMotion).
  bool replay = true;

  /// One message per bad field (empty = valid).
  std::vector<std::string> validate() const;
};

struct LensCalibrationResult {
  Calibration calibration;
  std::vector<RingDetection> detections;      ///< per frame (empty when nothing was detected)
  std::vector<std::string> detection_errors;  ///< per frame, empty string = detected
  std::optional<RingEstimate> ring;           ///< combined over the detected frames
  double margin_inner = 0.0, margin_outer = 0.0;
  std::optional<DirectionResult> direction;
  std::optional<OuterEdgeResult> outer_edge;
  std::vector<PairMotion> motions;
  std::vector<Provenance> provenance;
  std::vector<std::string> warnings;  ///< things a person should check (also in report())

  /// calibration.yaml text: a comment header with how every value was determined, then
  /// the plain YAML of DESIGN.md section 6 (Calibration::parse reads it back).
  std::string yaml() const;
  /// Human-readable report: the values, how each was found, the circles per frame and the
  /// replayed motion.
  std::string report() const;
  /// Short lines for the preview picture.
  std::vector<std::string> summaryLines() const;
};

/// Calibrates from `frames` (all the same size; 8-bit grey/BGR/BGRA). Throws
/// std::invalid_argument for invalid options, no frames or frames of different sizes, and
/// std::runtime_error when a value can be neither measured nor was given (e.g. no ring
/// found in any frame and no centre/radii by hand), naming what to pass.
LensCalibrationResult calibrateLens(std::span<const cv::Mat> frames,
                                    const LensCalibratorOptions& options);

/// The panorama proposal alone (see the file comment). Returns W, H, v_h.
struct PanoramaProposal {
  int width = 0;
  int height = 0;
  double horizon_row = 0.0;
  double horizon_radius = 0.0;
  double radial_scale = 0.0;   ///< px per radian of elevation used for H
};
PanoramaProposal proposePanorama(double radius_inner, double radius_outer, OuterEdge outer_edge,
                                 std::optional<int> width = {}, std::optional<int> height = {},
                                 std::optional<double> horizon_radius = {},
                                 std::optional<double> radial_scale = {});

/// Motion of every consecutive pair through the Pipeline (window = min(110, H)).
std::vector<PairMotion> replayPairs(std::span<const cv::Mat> frames, const Calibration& calibration);

}  // namespace omnipose::calibrate
