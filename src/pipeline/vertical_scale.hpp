#pragma once
/// \file vertical_scale.hpp
/// Each window's vertical scale alone (private to the core library), the in-window scale the
/// motion fit uses with MotionFit::Options::vertical_scale.
///
/// A translation expands a window seen at an angle more across than up: its vertical
/// expansion is what the model's ln s is (the window's inverse depth times the translation
/// towards it), its horizontal one adds the change of depth across the window. The log-polar
/// scale reads a mix of the two in a proportion the texture sets; the vertical scale alone has
/// no horizontal part to mix in. Against the exact renderer's box room it reads the looming
/// within 0.90-1.16 of the truth at every azimuth, the log-polar scale 0.75-1.61
/// (docs/results/ANALYSIS.md, "The in-window scale measured in the vertical alone").
///
/// For window k (columns first .. first + L - 1, rows top .. top + L - 1; L = window, first =
/// round(centre - (L - 1) / 2), wrapping around the panorama's columns):
///   c(y) = sum_x h(x) current(top + y, first + x) / sum_x h(x),   y = 0 .. L - 1,
///   r(v) = sum_x h(x) reference(v, first + x + du) / sum_x h(x)   (linear in u), every row v,
/// h the registration's taper (windowTaper()), du the window's measured shift: the window's
/// column profiles, each row's taper-weighted mean. Current row y is reference row
///   v(y) = vc + dv' + s (y - yc),   yc = (L - 1) / 2, vc = top + yc,
/// so (ln s, dv', gain a, offset b) minimise sum_y h(y) (c(y) - a r(v(y)) - b)^2, r sampled
/// linearly between rows; Gauss-Newton from (0, dv, 1, 0), at most kMaxIterations steps.
/// The scale's standard deviation is sqrt(N^-1_00 e) with N the fit's taper-weighted normal
/// matrix and e the taper-weighted mean squared residual. Masked pixels (the validity map) are
/// left out of each row's mean; a row with less than kMinRowWeight of its taper weight usable is
/// no sample.
///
/// A window is measured when it is valid with a translation and a rotation/scale peak
/// (confidence and rs_confidence above 0) and a shift within the panorama (|du| < W,
/// |dv| < H). Its WindowMotion::vertical_scale and vertical_scale_sigma are set when the fit
/// ends (its steps below the tolerances, or kMaxIterations steps taken) at |ln s| <=
/// kMaxLogScale with at least kMinSampleWeight of the rows' taper weight sampled and a finite,
/// positive sigma; otherwise (a singular step, and the windows not measured) they are 1 and 0.
///
/// Cost: two matrix-vector products over each window's pixels (the profiles) and a
/// 4-parameter fit of L samples, 2-4 Gauss-Newton steps: about 4 M instructions per pass at the
/// paper's 55 windows of 110 x 110 (callgrind, docs/PERFORMANCE.md), spread over the pool's
/// workers window by window. Realtime: the constructor allocates everything (scratch for every
/// worker of the pool it is given); measure() allocates nothing.

#include <opencv2/core.hpp>
#include <span>
#include <vector>

#include "omnipose/window_motion.hpp"
#include "runtime/worker_pool.hpp"

namespace omnipose::pipeline {

class VerticalScale {
 public:
  /// Gauss-Newton steps at most; it stops earlier once a step moves ln s by less than
  /// kLogScaleTolerance and the shift by less than kShiftTolerancePx.
  static constexpr int kMaxIterations = 10;
  static constexpr double kLogScaleTolerance = 1e-6;
  static constexpr double kShiftTolerancePx = 1e-4;
  /// The largest |ln s| accepted: the registration's own search range
  /// (WindowRegistration::Options::max_log_scale's default).
  static constexpr double kMaxLogScale = 0.2;
  /// A profile row counts when this share of its taper weight is usable (validity map) ...
  static constexpr double kMinRowWeight = 0.5;
  /// ... and a window's fit when this share of its rows' taper weight was sampled.
  static constexpr double kMinSampleWeight = 0.5;

  /// `validity`: Unwrapper::validity() (CV_32FC1, W x H, 1 = usable); windows of `window`
  /// pixels square whose top row is `top`, centred on the columns `centers` (one per window,
  /// WindowRegistration::windowCenter()); scratch for `workers` workers (the pool's size).
  /// Throws std::invalid_argument on a map of another type, no windows, windows that do not fit
  /// the map's rows, or fewer than 1 worker.
  VerticalScale(const cv::Mat& validity, int window, int top, std::vector<double> centers,
                int workers);

  /// Sets every window's vertical_scale and vertical_scale_sigma (see the file comment) for
  /// `windows` measured between `reference` and `current` (CV_32FC1, W x H, the panoramas the
  /// windows' shifts were measured on). Requires windows.size() == the constructor's window
  /// count and a pool of at most the constructor's workers; panoramas of another size or
  /// type leave every window unmeasured.
  void measure(const cv::Mat& reference, const cv::Mat& current, std::span<WindowMotion> windows,
               runtime::WorkerPool& pool) const;

 private:
  /// One worker's profiles: the current window's rows, the reference's rows (r(v) and whether
  /// row v counts), the shifted taper over L + 1 columns.
  struct Scratch {
    std::vector<double> current, reference;
    std::vector<char> current_ok, reference_ok;
    std::vector<float> weights;
    std::vector<float> sums;  ///< profile()'s scratch
  };
  /// Window k (first column `first`): the fit of the file comment; false when it fails.
  bool measureWindow(int first, const cv::Mat& reference, const cv::Mat& current,
                     WindowMotion& motion, Scratch& scratch) const;
  /// The weighted means of `n` columns of `rows` rows of `image` from row `row0` and column
  /// `first` (wrapping), weights `weights`, into mean[0 .. rows), ok[y] = 1 where a row
  /// counts: masked pixels left out unless all_valid_, the row counting when kMinRowWeight of
  /// the weight is usable. `sums`: scratch of `rows` floats.
  void profile(const cv::Mat& image, int row0, int rows, int first, const float* weights, int n,
               double* mean, char* ok, float* sums) const;

  cv::Mat validity_;
  int window_, top_, width_, height_;
  std::vector<double> centers_;
  std::vector<float> taper_;   ///< windowTaper() of every column of a window
  double taper_sum_ = 0.0;     ///< its sum
  bool all_valid_ = true;      ///< the validity map keeps every pixel (no lookups needed)
  mutable std::vector<Scratch> scratch_;  ///< one per worker
};

}  // namespace omnipose::pipeline
