#pragma once
/// \file ocamcalib_import.hpp
/// A calibration.yaml for a lens calibrated with Scaramuzza's OCamCalib toolbox
/// (`omnipose-calibrate --from-ocamcalib calib_results.txt`): the lens model is the file
/// itself; what is left to choose is the used ring, the robot's azimuth and the panorama.

#include <filesystem>
#include <opencv2/core.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "omnipose/calibration.hpp"

namespace omnipose::calibrate {

/// Choices left once a lens model is known (OCamCalib file, checkerboard calibration).
struct ModelImportOptions {
  std::optional<double> radius_inner;  ///< used ring, pixels; default: the file's ROI line
  std::optional<double> radius_outer;
  std::optional<AzimuthDirection> direction;  ///< default: measured (turn_left) or ccw, assumed and said so
  /// The frames given to importOcamCalib show the robot turning left in place: measure the
  /// azimuth direction from them (a mirrored capture flips it).
  bool turn_left = false;
  double forward_angle_deg = 0.0;      ///< image angle of the robot's +x axis, degrees
  int width = 1100;                    ///< panorama W (the paper's setting)
  int height = 110;                    ///< panorama H
  std::optional<double> horizon_row;   ///< default: elevation 0 in the middle, moved into the ring if needed
  /// Elevation kept clear at both ring edges, degrees (blur at the edges of a mirror).
  double edge_margin_deg = 1.0;
};

struct ModelImport {
  Calibration calibration;        ///< valid (validate() is empty)
  std::vector<std::string> notes; ///< how each value was determined, one line each
};

/// Sets c.panorama to W x H cylinder rows inside the elevations of c's ring (any lens model)
/// minus `edge_margin_deg` at both edges: the horizon in the middle when that fits, else
/// moved just enough (or `horizon_row` as given). Appends a note on how and returns it.
/// Throws std::runtime_error "ORIGIN: a W x H panorama does not fit ...: lower --height or
/// --width" when the ring is too narrow for H rows at this W.
std::string placePanoramaInRing(Calibration& c, int width, int height,
                                std::optional<double> horizon_row, double edge_margin_deg,
                                const std::string& origin, std::vector<std::string>& notes);

/// The steps every lens model shares once c.omni holds the model and the ring: the robot's
/// azimuth (given, measured from a turn-left sequence in `frames`, or assumed and said so),
/// the panorama inside the ring, validation. Notes are appended; throws std::runtime_error
/// prefixed by `origin` (see importOcamCalib).
void finishModelCalibration(Calibration& c, const ModelImportOptions& options,
                            std::span<const cv::Mat> frames, const std::string& origin,
                            std::vector<std::string>& notes);

/// Builds the calibration. `frames` (optional, the file's frame size) serve turn_left.
/// Throws std::runtime_error naming the file and the reason (an unreadable or invalid file,
/// no ROI line and no radii given, a panorama that does not fit into the ring's elevations,
/// a turn-left sequence that does not show a clear turn, with what to try).
ModelImport importOcamCalib(const std::filesystem::path& calib_results,
                                const ModelImportOptions& options,
                                std::span<const cv::Mat> frames = {});

}  // namespace omnipose::calibrate
