#pragma once
/// \file orientation.hpp
/// The lens orientation values of calibration.yaml that the donut's circles cannot give:
///  - azimuth_direction (cw | ccw) from a short sequence in which the robot turns left in
///    place (positive yaw). DESIGN.md section 2/3: content at column u of the current
///    panorama appears at u + du in the previous one and du * gamma = +omega_z, so a left
///    turn gives du > 0 with the right direction; the other direction mirrors the panorama
///    and flips the sign. (outer_edge flips rows only and azimuth_zero only rolls the
///    columns, so neither changes the sign of du.)
///  - outer_edge (top | bottom) from the expected appearance: the half of the ring that
///    looks up (sky, ceiling lights, windows) is brighter than the half that looks at the
///    floor (UpCue::kBright); kDark for the opposite; kNone uses the fallback.
///  - azimuth_zero_deg from a direction the user names (an angle or an image point).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "omnipose/calibration.hpp"

namespace omnipose::calibrate {

/// Circular shift along u between two equally sized panoramas (CV_32FC1 or CV_8UC1):
/// content at column u of `current` appears at u + du in `previous` (the sign of
/// cv::phaseCorrelate(current, previous) and of DESIGN.md section 2). Phase correlation of
/// the rows (the panorama is periodic in u), the cross-power spectra summed over all rows,
/// sub-pixel by a parabola through the peak.
struct ColumnShift {
  double du = 0.0;         ///< pixels, in (-W/2, W/2]
  double peak = 0.0;       ///< correlation peak height (1 = identical up to the shift)
  double peak_ratio = 0.0; ///< peak / highest value more than 3 columns away (> ~2: clear)
};
std::optional<ColumnShift> columnShift(const cv::Mat& previous, const cv::Mat& current);

/// How azimuth_direction was found from a turn-left sequence.
struct DirectionResult {
  AzimuthDirection direction = AzimuthDirection::kCw;
  bool decisive = false;            ///< false: too little motion or inconsistent pairs
  std::vector<ColumnShift> shifts;  ///< per consecutive pair, measured unwrapped with cw
  double total_du_cw = 0.0;         ///< sum of du over the pairs (cw), pixels
  double total_yaw_deg = 0.0;       ///< |sum du| * gamma, degrees
  std::string how;                  ///< one line for the report
};

/// Unwraps every frame with `calibration` forced to cw, measures du for each consecutive
/// pair and chooses the direction for which the sequence turns left. Frames must all have
/// the calibration's image size. Decisive when |sum du| >= min_total_px and at least
/// two thirds of the pairs that moved (|du| >= 0.5 px) agree with the sum's sign.
/// Throws std::invalid_argument for fewer than 2 frames or an invalid calibration.
DirectionResult directionFromTurnLeft(std::span<const cv::Mat> frames,
                                      const Calibration& calibration, double min_total_px = 1.0);

/// Vertical appearance cue for outer_edge.
enum class UpCue {
  kBright,  ///< the upward-looking side is brighter (sky, ceiling, lights, windows)
  kDark,    ///< the upward-looking side is darker
  kNone,    ///< no cue: use the fallback
};
/// "bright" | "dark" | "none"; throws std::invalid_argument naming the value otherwise.
UpCue parseUpCue(const std::string& name);
const char* toString(UpCue cue);

struct OuterEdgeResult {
  OuterEdge edge = OuterEdge::kTop;
  bool decisive = false;       ///< false: the fallback was used
  double inner_level = 0.0;    ///< brightest-quarter mean grey of the inner quarter of the ring
  double outer_level = 0.0;    ///< the same for the outer quarter
  double contrast = 0.0;       ///< (outer - inner) / (outer + inner)
  std::string how;             ///< one line for the report
};

/// Compares the inner and outer quarters of the used ring (samples on equally spaced rays
/// of all frames; statistic: the mean of the brightest quarter of each band's samples, as
/// lights, windows and sky are the brightest things and they are up) under `cue`;
/// decisive when |contrast| >= min_contrast.
OuterEdgeResult outerEdgeFromAppearance(std::span<const cv::Mat> frames,
                                        const OmniLens& lens, UpCue cue, OuterEdge fallback,
                                        double min_contrast = 0.05);

/// Image angle a = atan2(y - cy, x - cx) of an image point, degrees in [0, 360).
double imageAngleDeg(const OmniLens& lens, const Eigen::Vector2d& point);

/// Which way an unmirrored camera image runs for each outer edge (used when no turn-left
/// sequence is given). A camera looking up at a mirror above it (outer ring = up) sees
/// world azimuth theta at image angle a = theta: cw. Looking down at a mirror below it
/// (outer ring = down), image y runs along world -y: a = -theta, ccw. A mirrored screen
/// capture (front-camera preview) flips either.
AzimuthDirection assumedDirection(OuterEdge outer_edge);

}  // namespace omnipose::calibrate
