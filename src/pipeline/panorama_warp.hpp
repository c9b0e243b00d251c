#pragma once
// Warps a panorama by a camera motion with the exact cylinder projection (private).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <vector>

#include "omnipose/calibration.hpp"

namespace omnipose {

/// Given (R, tau) with P_prev = R P_cur + tau (all points at unit horizontal distance in
/// the previous frame), writes J(u, v) = I_cur(project(R^T (X_prev(u, v) - tau))), so that
/// J looks like the previous panorama when the motion is right (bicubic sampling). The exact projection is
/// evaluated on a coarse grid (every kGridStep columns and rows) and interpolated; the
/// map is smooth, the interpolation error is below 0.01 px for motions up to 0.3 rad.
/// Allocation-free after construction.
class PanoramaWarp {
 public:
  explicit PanoramaWarp(const PanoramaGeometry& geometry);

  /// `current` and `out`: CV_32FC1, W x H; `out` must be allocated and distinct.
  void warp(const cv::Mat& current, const Eigen::Matrix3d& R, const Eigen::Vector3d& tau,
            cv::Mat& out);

 private:
  static constexpr int kGridStep = 4;
  static constexpr int kPad = 160;  ///< columns of wrap-around padding on each side

  PanoramaGeometry geometry_;
  int grid_cols_ = 0, grid_rows_ = 0;
  std::vector<float> grid_du_, grid_dv_;  ///< displacement at grid points, pixels
  cv::Mat padded_;                        ///< current panorama with wrapped borders
};

}  // namespace omnipose
