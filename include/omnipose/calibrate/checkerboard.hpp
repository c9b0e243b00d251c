#pragma once
/// \file checkerboard.hpp
/// `omnipose-calibrate --checkerboard COLSxROWS --square METRES IMAGES...`: the Mei (unified)
/// model of a catadioptric lens from checkerboard views, with OpenCV's cv::omnidir::calibrate.
/// COLSxROWS counts the board's inner corners (OpenCV's pattern size), e.g. 9x6 for a board
/// of 10 x 7 squares.

#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <vector>

#include "omnipose/calibrate/ocamcalib_import.hpp"
#include "omnipose/lens_model.hpp"

namespace omnipose::calibrate {

struct CheckerboardOptions {
  int cols = 9;            ///< inner corners per row
  int rows = 6;            ///< inner corners per column
  double square_m = 0.025; ///< side of a square, metres
  int min_views = 3;       ///< boards found needed for a calibration
};

struct CheckerboardCalibration {
  MeiModel model;
  double rms_px = 0.0;             ///< reprojection error of the used views, pixels
  int views_found = 0;             ///< images in which the board was found
  int views_used = 0;              ///< of those, the ones omnidir kept after initialisation
  std::vector<std::string> notes;  ///< per image: found or not; the result
};

/// Parses "COLSxROWS"; throws std::invalid_argument naming the text otherwise.
void parsePatternSize(const std::string& text, CheckerboardOptions& options);

/// Finds the board in every image (8-bit grey or colour, one size) and calibrates. Throws
/// std::runtime_error naming the problem: a bad option, fewer boards found than min_views
/// (listing the images), omnidir failing to converge.
CheckerboardCalibration calibrateCheckerboard(std::span<const cv::Mat> images,
                                              const CheckerboardOptions& options);

/// A calibration.yaml for the `mei` model from checkerboard views: the model from
/// calibrateCheckerboard(), the ring given (options.radius_inner/outer) or detected about
/// the model's centre in the same images, then finishModelCalibration(). Throws
/// std::runtime_error naming the problem and what to try.
ModelImport importCheckerboard(std::span<const cv::Mat> images, const CheckerboardOptions& board,
                                   const ModelImportOptions& options);

}  // namespace omnipose::calibrate
