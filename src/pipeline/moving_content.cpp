#include "pipeline/moving_content.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "common/periodic.hpp"

namespace omnipose::pipeline {
namespace {

using detail::wrapIndex;

/// The median of a chi-square variable with one degree of freedom: median(e^2) / this is
/// the variance of Gaussian e.
constexpr double kChiSquareMedian = 0.4549;

}  // namespace

MovingContentCheck::MovingContentCheck(const cv::Mat& validity, int window, int top,
                                       std::vector<double> centers)
    : validity_(validity.clone()),
      window_(window),
      top_(top),
      width_(validity.cols),
      centers_(std::move(centers)) {
  if (validity_.empty() || validity_.type() != CV_32FC1)
    throw std::invalid_argument("moving-content check: the validity map must be CV_32FC1");
  if (centers_.empty() || window_ < 4 || top_ < 0 || top_ + window_ > validity_.rows)
    throw std::invalid_argument("moving-content check: " + std::to_string(centers_.size()) +
                                " windows of " + std::to_string(window_) + " rows from row " +
                                std::to_string(top_) + " in " + std::to_string(validity_.rows) +
                                " rows");
  // Sample rows 1, 1 + kStride, ... of the windows (not the outermost, whose taper is ~0).
  sample_rows_ = (window_ - 3) / kStride + 1;
  sample_cols_ = (width_ + kStride - 1) / kStride;
  for (int j = 0; j < window_; ++j) taper_.push_back(windowTaper(j, window_));
  motion_.resize(static_cast<std::size_t>(width_));
  samples_.resize(static_cast<std::size_t>(sample_rows_) * sample_cols_);
  residuals_.resize(samples_.size());
  column_usable_.resize(static_cast<std::size_t>(sample_cols_));
  column_disagreeing_.resize(static_cast<std::size_t>(sample_cols_));
  node_.resize(centers_.size());
  row_sums_.resize(static_cast<std::size_t>(sample_rows_));
  all_valid_ = cv::countNonZero(validity_ < 1.0f) == 0;
  // Each window's sample columns (u = c * kStride within the window, the outermost columns
  // left out as the outermost rows) and their taper weights.
  const double half = 0.5 * (window_ - 1);
  window_columns_begin_.push_back(0);
  for (const double center : centers_) {
    const int first = static_cast<int>(std::lround(center - half));
    for (int j = 1; j < window_ - 1; ++j) {
      const int u = wrapIndex(first + j, width_);
      if (u % kStride != 0) continue;
      window_columns_.push_back(
          {static_cast<std::size_t>(u / kStride), taper_[static_cast<std::size_t>(j)]});
    }
    window_columns_begin_.push_back(static_cast<int>(window_columns_.size()));
  }
}

double MovingContentCheck::weight(double f) {
  return std::clamp((kDropFraction - f) / (kDropFraction - kKeepFraction), 0.0, 1.0);
}

bool MovingContentCheck::interpolateMotion(std::span<const WindowMotion> windows,
                                           std::span<const Eigen::Vector2d> expected) {
  const int n = static_cast<int>(windows.size());
  const auto usable = [&](int k) {
    return windows[static_cast<std::size_t>(k)].valid &&
           windows[static_cast<std::size_t>(k)].confidence > 0.0;
  };
  // A window whose shift is an outlier among its neighbours' or against the last fit's
  // prediction (it locked onto a person, not the background) is no node: the windows next
  // to it would inherit the person's motion.
  for (int k = 0; k < n; ++k) {
    node_[static_cast<std::size_t>(k)] = 0;
    if (!usable(k)) continue;
    int m = 0;
    for (int j = k - kNeighbours; j <= k + kNeighbours; ++j) {
      const int i = wrapIndex(j, n);
      if (!usable(i)) continue;
      neighbour_du_[static_cast<std::size_t>(m)] = windows[static_cast<std::size_t>(i)].du;
      neighbour_dv_[static_cast<std::size_t>(m)] = windows[static_cast<std::size_t>(i)].dv;
      ++m;
    }
    const auto median = [m](std::array<double, 2 * kNeighbours + 1>& values) {
      const auto middle = values.begin() + m / 2;
      std::nth_element(values.begin(), middle, values.begin() + m);
      return *middle;
    };
    const WindowMotion& w = windows[static_cast<std::size_t>(k)];
    node_[static_cast<std::size_t>(k)] = std::abs(w.du - median(neighbour_du_)) <= kOutlierPx &&
                                         std::abs(w.dv - median(neighbour_dv_)) <= kOutlierPx;
    if (!expected.empty()) {
      const Eigen::Vector2d& e = expected[static_cast<std::size_t>(k)];
      if (!(std::abs(w.du - e.x()) <= kOutlierPx && std::abs(w.dv - e.y()) <= kOutlierPx))
        node_[static_cast<std::size_t>(k)] = 0;
    }
  }
  const auto measured = [&](int k) { return node_[static_cast<std::size_t>(k)] != 0; };
  int count = 0, first = -1;
  for (int k = 0; k < n; ++k) {
    if (!measured(k)) continue;
    if (first < 0) first = k;
    ++count;
  }
  for (ColumnMotion& m : motion_) m.known = false;
  if (count < kMinWindows) return false;
  const auto at = [&](int k) {
    const WindowMotion& w = windows[static_cast<std::size_t>(k)];
    // The stretch along v is the vertical scale where it was measured.
    const double scale = w.vertical_scale_sigma > 0.0 ? w.vertical_scale : w.scale;
    return ColumnMotion{static_cast<float>(w.du), static_cast<float>(w.dv),
                        static_cast<float>(scale * w.rotation),
                        static_cast<float>(scale - 1.0), true};
  };
  // Between consecutive measured windows a and b (around the ring), columns from a's centre
  // to b's.
  int a = first;
  for (int step = 0; step < count; ++step) {
    int b = a + 1;
    while (!measured(b % n)) ++b;
    b %= n;
    const ColumnMotion ma = at(a), mb = at(b);
    const double ca = centers_[static_cast<std::size_t>(a)];
    double cb = centers_[static_cast<std::size_t>(b)];
    if (cb <= ca) cb += width_;
    for (int u = static_cast<int>(std::ceil(ca)); u < cb; ++u) {
      const float t = static_cast<float>((u - ca) / (cb - ca));
      motion_[static_cast<std::size_t>(wrapIndex(u, width_))] = {
          ma.du + t * (mb.du - ma.du), ma.dv + t * (mb.dv - ma.dv),
          ma.shear + t * (mb.shear - ma.shear), ma.stretch + t * (mb.stretch - ma.stretch), true};
    }
    a = b;
  }
  return true;
}

void MovingContentCheck::sampleRow(int r, const cv::Mat& reference, const cv::Mat& current,
                                   const PanoramaWarp& warp) {
  const int W = width_, H = reference.rows;
  const int v = top_ + 1 + r * kStride;
  const float y = static_cast<float>(v - top_) - 0.5f * static_cast<float>(window_ - 1);
  Sample* out = &samples_[static_cast<std::size_t>(r) * sample_cols_];
  const float* ref_row = reference.ptr<float>(v);
  const float* ref_up = reference.ptr<float>(std::max(v - 1, 0));
  const float* ref_down = reference.ptr<float>(std::min(v + 1, H - 1));
  const float* cur_row = current.ptr<float>(v);
  const float* valid_row = validity_.ptr<float>(v);
  // Whether a pixel of this row may come from beyond the panorama's rows in the frame before
  // the de-rotation (a large tilt); most rows' range says no for all of them at once.
  const auto [dv_low, dv_high] = warp.rowDisplacementRange(v);
  const bool check_source = !all_valid_ || static_cast<float>(v) + dv_low < 0.0f ||
                            static_cast<float>(v) + dv_high > static_cast<float>(H - 1);
  const auto usable = [&](int row, int column) {
    return all_valid_ || validity_.at<float>(row, column) >= 1.0f;
  };
  RowSums sums;
  for (int c = 0; c < sample_cols_; ++c) {
    Sample& s = out[c];
    s.usable = false;
    const int u = c * kStride;
    const ColumnMotion& m = motion_[static_cast<std::size_t>(u)];
    if (!m.known || (!all_valid_ && valid_row[u] < 1.0f)) continue;
    if (check_source) {
      const Eigen::Vector2f source = warp.gridDisplacement(u, v);
      const float source_v = static_cast<float>(v) + source.y();
      if (!(source_v >= 0.0f && source_v <= static_cast<float>(H - 1))) continue;
      if (!usable(static_cast<int>(source_v + 0.5f),
                  wrapIndex(static_cast<int>(std::lround(static_cast<float>(u) + source.x())), W)))
        continue;
    }
    // The reference where the motion puts this pixel (bilinear). fu + W > 0 for any motion
    // under a panorama's width, so truncation is the floor.
    const float fu = static_cast<float>(u + W) + m.du + m.shear * y;
    const float fv = static_cast<float>(v) + m.dv + m.stretch * y;
    if (!(fv >= 0.0f && fv < static_cast<float>(H - 1) && fu >= 0.0f &&
          fu < static_cast<float>(3 * W)))
      continue;
    const int r0 = static_cast<int>(fv);
    int c0 = static_cast<int>(fu);
    const float au = fu - static_cast<float>(c0), av = fv - static_cast<float>(r0);
    c0 -= c0 >= 2 * W ? 2 * W : W;
    if (c0 < 0) c0 += W;
    const int c1 = c0 + 1 == W ? 0 : c0 + 1;
    if (!usable(r0, c0) || !usable(r0 + 1, c1)) continue;
    const float* q0 = reference.ptr<float>(r0);
    const float* q1 = reference.ptr<float>(r0 + 1);
    s.p = (1.0f - av) * ((1.0f - au) * q0[c0] + au * q0[c1]) +
          av * ((1.0f - au) * q1[c0] + au * q1[c1]);
    s.c = cur_row[u];
    const float gx = 0.5f * (ref_row[u + 1 == W ? 0 : u + 1] - ref_row[u == 0 ? W - 1 : u - 1]);
    const float gy = 0.5f * (ref_down[u] - ref_up[u]);
    s.gradient2 = gx * gx + gy * gy;
    s.usable = true;
    sums.n += 1.0;
    sums.p += s.p;
    sums.c += s.c;
    sums.pp += static_cast<double>(s.p) * s.p;
    sums.pc += static_cast<double>(s.p) * s.c;
  }
  row_sums_[static_cast<std::size_t>(r)] = sums;
}

void MovingContentCheck::measure(const cv::Mat& reference, const cv::Mat& current,
                                 const PanoramaWarp& warp, std::span<const WindowMotion> windows,
                                 runtime::WorkerPool& pool, std::span<double> fraction,
                                 std::span<const Eigen::Vector2d> expected) {
  std::fill(fraction.begin(), fraction.end(), 0.0);
  if (windows.size() != centers_.size() || fraction.size() != centers_.size() ||
      (!expected.empty() && expected.size() != centers_.size()))
    return;
  if (!interpolateMotion(windows, expected)) return;
  auto sample = [&](int, int r) { sampleRow(r, reference, current, warp); };
  pool.run(sample_rows_, sample);

  // The pair's gain and offset, and the noise of what they leave.
  RowSums sums;
  for (const RowSums& row : row_sums_) {
    sums.n += row.n;
    sums.p += row.p;
    sums.c += row.c;
    sums.pp += row.pp;
    sums.pc += row.pc;
  }
  if (sums.n < kMinSamples) return;
  const double mean_p = sums.p / sums.n, mean_c = sums.c / sums.n;
  const double var_p = sums.pp / sums.n - mean_p * mean_p;
  const double cov = sums.pc / sums.n - mean_p * mean_c;
  const float a = static_cast<float>(var_p > 0.0 ? cov / var_p : 1.0);
  const float b = static_cast<float>(mean_c - a * mean_p);
  for (std::size_t i = 0; i < samples_.size(); ++i) {
    const Sample& s = samples_[i];
    const float e = s.c - (a * s.p + b);
    residuals_[i] = s.usable ? e * e : std::numeric_limits<float>::infinity();
  }
  // The unusable samples sort last: the (n / 2)-th smallest is the usable samples' median.
  const auto middle = residuals_.begin() + static_cast<std::ptrdiff_t>(sums.n / 2);
  std::nth_element(residuals_.begin(), middle, residuals_.end());
  const float noise_threshold =
      static_cast<float>(kNoiseSigmas * kNoiseSigmas * (*middle / kChiSquareMedian));
  const float gradient_factor = static_cast<float>(kShiftTolerancePx * kShiftTolerancePx);

  // Per sample column: how much of its (row-tapered) weight is usable, and counts.
  std::fill(column_usable_.begin(), column_usable_.end(), 0.0);
  std::fill(column_disagreeing_.begin(), column_disagreeing_.end(), 0.0);
  for (int r = 0; r < sample_rows_; ++r) {
    Sample* row = &samples_[static_cast<std::size_t>(r) * sample_cols_];
    const double w = taper_[static_cast<std::size_t>(1 + r * kStride)];
    for (int c = 0; c < sample_cols_; ++c) {
      Sample& s = row[c];
      const float e = s.c - (a * s.p + b);
      s.disagrees = s.usable && e * e > noise_threshold + gradient_factor * s.gradient2;
    }
    for (int c = 0; c < sample_cols_; ++c) {
      const Sample& s = row[c];
      if (!s.usable) continue;
      column_usable_[static_cast<std::size_t>(c)] += w;
      const bool left = row[c == 0 ? sample_cols_ - 1 : c - 1].disagrees;
      const bool right = row[c + 1 == sample_cols_ ? 0 : c + 1].disagrees;
      if (s.disagrees && (left || right)) column_disagreeing_[static_cast<std::size_t>(c)] += w;
    }
  }
  // Per window: the same over its sample columns, tapered along u.
  for (std::size_t k = 0; k < centers_.size(); ++k) {
    if (!windows[k].valid) continue;
    double usable = 0.0, disagreeing = 0.0;
    for (int i = window_columns_begin_[k]; i < window_columns_begin_[k + 1]; ++i) {
      const WindowColumn& column = window_columns_[static_cast<std::size_t>(i)];
      usable += column.weight * column_usable_[column.index];
      disagreeing += column.weight * column_disagreeing_[column.index];
    }
    fraction[k] = usable > 0.0 ? disagreeing / usable : 0.0;
  }
}

}  // namespace omnipose::pipeline
