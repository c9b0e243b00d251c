#pragma once
// De-rotates a panorama by a camera rotation with the exact cylinder projection (private).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <utility>
#include <vector>

#include "omnipose/calibration.hpp"

namespace omnipose {

/// Given R with P_prev = R P_cur + t, writes J(u, v) = I_cur(project(R^T X_prev(u, v))):
/// the current panorama as seen with the previous camera's orientation from the current
/// camera's centre (bicubic sampling), so that only translation and the residual rotation
/// are left between J and the previous panorama. The exact projection is evaluated on a
/// coarse grid (every kGridStep columns and rows) and interpolated; the map is smooth, the
/// interpolation error is below 0.01 px for rotations up to 0.3 rad.
/// Allocation-free after construction.
class PanoramaWarp {
 public:
  explicit PanoramaWarp(const PanoramaGeometry& geometry);

  // The de-rotation runs in two stages, so that the work can be shared between threads:
  // 1. padCurrent() and projectGridRows() over all gridRows(), concurrently (the latter on
  //    disjoint ranges of grid rows);
  // 2. when all of stage 1 has returned, derotateRows() over all rows of `out`,
  //    concurrently on disjoint ranges.
  // How the ranges are split does not change the result. `current` and `out`: CV_32FC1,
  // W x H; `out` is allocated and distinct from `current`.

  /// Copies `current` with wrapped columns and repeated edge rows (so that no pixel needs a
  /// modulo or a clamp).
  void padCurrent(const cv::Mat& current);
  /// Evaluates the exact projection of R at grid rows [first, last) of gridRows().
  void projectGridRows(const Eigen::Matrix3d& R, int first, int last);
  int gridRows() const { return grid_rows_; }
  /// Writes rows [first, last) of `out`.
  void derotateRows(cv::Mat& out, int first, int last) const;

  /// The exact displacement (du, dv), pixels, of the de-rotation by R at panorama point
  /// (u, v): `out` at (u, v) samples `current` at (u + du, v + dv) (the grid interpolates
  /// this). du is the azimuth change wrapped to (-W/2, W/2].
  Eigen::Vector2d displacementAt(const Eigen::Matrix3d& R, double u, double v) const;
  /// The displacement of the last projectGridRows() at pixel (u, v) as derotateRows()
  /// interpolates it from the grid, pixels. Requires 0 <= u < W, 0 <= v < H.
  Eigen::Vector2f gridDisplacement(int u, int v) const;
  /// The least and the greatest row displacement dv that gridDisplacement() gives anywhere
  /// on row v (bounds from the two grid rows it interpolates between). Requires 0 <= v < H.
  std::pair<float, float> rowDisplacementRange(int v) const;

 private:
  /// displacementAt() for the unit-cylinder point (cos theta, sin theta, h) at row v, given
  /// R^T.
  Eigen::Vector2d displacement(const Eigen::Matrix3d& Rt, double cos_theta, double sin_theta,
                               double h, double v) const;

  static constexpr int kGridStep = 4;
  static constexpr int kPad = 160;  ///< columns of wrap-around padding on each side
  static constexpr int kPadRows = 3;  ///< rows repeating the edge row above and below

  PanoramaGeometry geometry_;
  int grid_cols_ = 0, grid_rows_ = 0;
  std::vector<float> grid_du_, grid_dv_;  ///< displacement at grid points, pixels
  // Start-up tables: the unit-cylinder point of every grid column and row, so projectGridRows()
  // evaluates no sine or cosine per frame.
  std::vector<double> grid_cos_, grid_sin_;  ///< per grid column
  std::vector<double> grid_h_;               ///< per grid row
  cv::Mat padded_;  ///< current panorama with wrapped columns and repeated edge rows
};

}  // namespace omnipose
