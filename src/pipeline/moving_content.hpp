#pragma once
/// \file moving_content.hpp
/// Content that moves on its own (private to the core library): people walking by, a door
/// swinging. A window that such content covers in part keeps its phase-correlation peak on
/// the background, but the peak is pulled by a fraction of a pixel, below anything the fit's
/// robust loss can tell from noise; over a fifth of the ring (three people at arm's length)
/// that bias was the largest error of a slow turn. The check looks at the pixels instead of
/// the peaks: the reference is moved onto the current panorama by the motion the windows
/// measured, and the pixels that motion does not explain are counted per window. Background
/// leaves sensor noise; a person walking at a different speed leaves their outline and
/// texture. Parallax is no trouble: the motion is the windows' own, not a global model's.
///
/// The motion at pixel (u, v): each window's measured shift (du, dv), in-window scale s (its
/// vertical scale where measured, WindowMotion::vertical_scale) and
/// rotation phi give (du + s phi y, dv + (s - 1) y) at its centre column, y = v - the
/// windows' centre row; between two window centres the four numbers are interpolated
/// linearly in u (windows without a peak, and windows off their neighbours' shifts, see
/// kOutlierPx, are skipped). At sample pixels x (every
/// kStride-th row and column of the windows' rows):
///   p(x) = reference(x + d(x)) (bilinear), c(x) = current(x);
///   e(x) = c(x) - (a p(x) + b), a and b the pair's least-squares gain and offset (an
///          exposure step moves nothing);
///   sigma^2 = median of e^2 over the samples / 0.455 (the median of a chi-square with one
///          degree of freedom): noise, JPEG and interpolation as this pair has them;
///   x disagrees when e(x)^2 > kNoiseSigmas^2 sigma^2 + (kShiftTolerancePx |grad|)^2, the
///          second term leaving the misfit of the interpolated motion near strong edges;
///   x counts when it and a horizontal neighbour sample disagree: a person's outline moved
///          by a few pixels is wider than one sample, a noise speck or the one-sample line
///          that a wall corner's kink in the parallax leaves (the motion is interpolated
///          linearly between window centres) is not;
///   fraction_k = the taper-weighted share of window k's usable samples that count.
/// Usable samples are those the static validity map keeps in the reference and, through
/// the de-rotation, in the current frame (rows a large tilt brings in from beyond the
/// panorama are not content that moved).
///
/// Realtime: the constructor allocates everything; measure() allocates nothing.

#include <Eigen/Core>
#include <array>
#include <opencv2/core.hpp>
#include <span>
#include <vector>

#include "omnipose/window_motion.hpp"
#include "pipeline/panorama_warp.hpp"
#include "runtime/worker_pool.hpp"

namespace omnipose::pipeline {

class MovingContentCheck {
 public:
  /// A sample disagrees beyond this many noise sigmas ...
  static constexpr double kNoiseSigmas = 4.0;
  /// ... plus this shift's worth of its gradient (pixels).
  static constexpr double kShiftTolerancePx = 1.0;
  /// Fractions up to kKeepFraction leave a window's confidence whole (noise has heavier
  /// tails than a Gaussian after JPEG); from kDropFraction on the window is left out; the
  /// weight falls linearly between them (weight()).
  static constexpr double kKeepFraction = 0.01;
  static constexpr double kDropFraction = 0.06;
  /// Sample spacing, pixels, along both axes: a person is tens of pixels wide.
  static constexpr int kStride = 3;
  /// A window is a node of the interpolated motion when its du and dv are each within
  /// kOutlierPx of the median of the windows within kNeighbours of it (itself included),
  /// and of the shift the last fit predicts for it when measure() is given that: a window
  /// that locked onto a person walking a few pixels per frame faster than the background is
  /// none. Nine windows span 1.7 window widths, more than one person near the robot covers;
  /// the median of a smooth parallax field (a monotonic run of shifts) is the window's own
  /// shift. Two people side by side can make the median theirs; the prediction of a fit
  /// over the whole ring, whose robust loss left their windows out, is the background's.
  static constexpr int kNeighbours = 4;
  static constexpr double kOutlierPx = 1.0;
  /// Fewer nodes (windows measured and not outliers) than this, or fewer usable samples
  /// than kMinSamples: no check (every fraction 0).
  static constexpr int kMinWindows = 8;
  static constexpr int kMinSamples = 256;

  /// `validity`: Unwrapper::validity() (CV_32FC1, W x H, 1 = usable); windows of `window`
  /// pixels square whose top row is `top`, centred on the increasing columns `centers` (one
  /// per window, WindowRegistration::windowCenter()). Throws std::invalid_argument on a map
  /// of another type, no windows, or windows that do not fit the map's rows.
  MovingContentCheck(const cv::Mat& validity, int window, int top, std::vector<double> centers);

  /// Fills `fraction` (one per window of `windows`, in [0, 1]) for `windows` measured between
  /// `reference` and `current` (CV_32FC1, W x H): `current` is the current panorama as the
  /// last PanoramaWarp::projectGridRows() of `warp` de-rotated it. A window that is not
  /// valid or has no usable sample gets 0. `expected`: empty, or per window the shift (du,
  /// dv), pixels, that the motion fitted so far predicts for it (see kOutlierPx). Requires
  /// windows.size() == fraction.size() (== expected.size() when given) == the constructor's
  /// window count.
  void measure(const cv::Mat& reference, const cv::Mat& current, const PanoramaWarp& warp,
               std::span<const WindowMotion> windows, runtime::WorkerPool& pool,
               std::span<double> fraction, std::span<const Eigen::Vector2d> expected = {});

  /// The factor on a window's confidences for a moving fraction `f`: 1 up to kKeepFraction,
  /// 0 from kDropFraction, linear between.
  static double weight(double f);

 private:
  /// The interpolated motion of one column: d(v) = (du + shear y, dv + stretch y).
  struct ColumnMotion {
    float du = 0.0f, dv = 0.0f, shear = 0.0f, stretch = 0.0f;
    bool known = false;
  };
  /// One sample: reference at the motion p, current c, squared gradient of the reference.
  struct Sample {
    float p = 0.0f, c = 0.0f, gradient2 = 0.0f;
    bool usable = false;
    bool disagrees = false;
  };
  /// Fills node_ and motion_ from the windows; false when fewer than kMinWindows are nodes.
  bool interpolateMotion(std::span<const WindowMotion> windows,
                         std::span<const Eigen::Vector2d> expected);
  /// Samples of sample row `r` (row top_ + r * kStride) into samples_.
  void sampleRow(int r, const cv::Mat& reference, const cv::Mat& current,
                 const PanoramaWarp& warp);

  cv::Mat validity_;
  int window_, top_, width_;
  std::vector<double> centers_;
  int sample_rows_, sample_cols_;
  std::vector<double> taper_;  ///< windowTaper() of every sample index of a window
  std::vector<ColumnMotion> motion_;  ///< per panorama column
  std::vector<Sample> samples_;       ///< sample_rows_ x sample_cols_
  std::vector<float> residuals_;  ///< scratch: e^2 per sample, +inf if unusable (the median)
  /// Per sample column: taper-weighted (over rows) count of usable and disagreeing samples.
  std::vector<double> column_usable_, column_disagreeing_;
  /// Per sample row: sums over its usable samples for the pair's gain and offset.
  struct RowSums {
    double n = 0.0, p = 0.0, c = 0.0, pp = 0.0, pc = 0.0;
  };
  std::vector<RowSums> row_sums_;
  /// A sample column of a window and its taper weight along u.
  struct WindowColumn {
    std::size_t index;
    double weight;
  };
  std::vector<WindowColumn> window_columns_;
  std::vector<int> window_columns_begin_;  ///< window k's are [begin[k], begin[k + 1])
  bool all_valid_ = true;  ///< the validity map keeps every pixel (no lookups needed)
  std::vector<char> node_;  ///< per window: a node of the interpolation (interpolateMotion())
  std::array<double, 2 * kNeighbours + 1> neighbour_du_{}, neighbour_dv_{};  ///< scratch
};

}  // namespace omnipose::pipeline
