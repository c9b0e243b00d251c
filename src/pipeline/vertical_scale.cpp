#include "pipeline/vertical_scale.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <Eigen/LU>

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>

#include "common/periodic.hpp"

namespace omnipose::pipeline {
namespace {

using detail::wrapIndex;

/// A row-major float matrix view: `rows` rows of `cols` columns from `data`, rows `stride`
/// floats apart.
using RowMajorFloats = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
using RowsView = Eigen::Map<const RowMajorFloats, Eigen::Unaligned, Eigen::OuterStride<>>;

}  // namespace

VerticalScale::VerticalScale(const cv::Mat& validity, int window, int top,
                             std::vector<double> centers, int workers)
    : validity_(validity.clone()),
      window_(window),
      top_(top),
      width_(validity.cols),
      height_(validity.rows),
      centers_(std::move(centers)) {
  if (validity_.empty() || validity_.type() != CV_32FC1)
    throw std::invalid_argument("vertical scale: the validity map must be CV_32FC1");
  if (centers_.empty() || window_ < 4 || window_ > width_ || top_ < 0 ||
      top_ + window_ > height_ || workers < 1)
    throw std::invalid_argument("vertical scale: " + std::to_string(centers_.size()) +
                                " windows of " + std::to_string(window_) + " pixels from row " +
                                std::to_string(top_) + " in a " + std::to_string(width_) + " x " +
                                std::to_string(height_) + " panorama, " +
                                std::to_string(workers) + " workers");
  for (int j = 0; j < window_; ++j) {
    taper_.push_back(static_cast<float>(windowTaper(j, window_)));
    taper_sum_ += taper_.back();
  }
  all_valid_ = cv::countNonZero(validity_ < 1.0f) == 0;
  scratch_.resize(static_cast<std::size_t>(workers));
  for (Scratch& s : scratch_) {
    s.sums.resize(static_cast<std::size_t>(height_));
    s.current.resize(static_cast<std::size_t>(window_));
    s.current_ok.resize(static_cast<std::size_t>(window_));
    s.reference.resize(static_cast<std::size_t>(height_));
    s.reference_ok.resize(static_cast<std::size_t>(height_));
    s.weights.resize(static_cast<std::size_t>(window_) + 1);
  }
}

void VerticalScale::profile(const cv::Mat& image, int row0, int rows, int first,
                            const float* weights, int n, double* mean, char* ok,
                            float* sums) const {
  const int u0 = wrapIndex(first, width_);
  const int n1 = std::min(n, width_ - u0);  // columns before the wrap
  if (all_valid_) {
    // Two matrix-vector products (before and after the wrap), vectorised by Eigen.
    const Eigen::OuterStride<> stride(static_cast<Eigen::Index>(image.step1()));
    Eigen::Map<Eigen::VectorXf> out(sums, rows);
    out.noalias() = RowsView(image.ptr<float>(row0) + u0, rows, n1, stride) *
                    Eigen::Map<const Eigen::VectorXf>(weights, n1);
    if (n > n1)
      out.noalias() += RowsView(image.ptr<float>(row0), rows, n - n1, stride) *
                       Eigen::Map<const Eigen::VectorXf>(weights + n1, n - n1);
    for (int y = 0; y < rows; ++y) {
      mean[y] = sums[y] / taper_sum_;
      ok[y] = 1;
    }
    return;
  }
  for (int y = 0; y < rows; ++y) {
    const float* row = image.ptr<float>(row0 + y);
    const float* valid = validity_.ptr<float>(row0 + y);
    double sum = 0.0, weight = 0.0;
    for (int j = 0; j < n; ++j) {
      const int u = j < n1 ? u0 + j : j - n1;
      const double w = static_cast<double>(weights[j]) * valid[u];
      sum += w * row[u];
      weight += w;
    }
    ok[y] = weight >= kMinRowWeight * taper_sum_ ? 1 : 0;
    mean[y] = ok[y] ? sum / weight : 0.0;
  }
}

bool VerticalScale::measureWindow(int first, const cv::Mat& reference, const cv::Mat& current,
                                  WindowMotion& motion, Scratch& s) const {
  const int L = window_;
  // The current window's profile c(y).
  profile(current, top_, L, first, taper_.data(), L, s.current.data(), s.current_ok.data(),
          s.sums.data());
  // The reference's profile r(v), its columns shifted by du: linear interpolation in u is the
  // taper moved by the fraction over L + 1 whole columns.
  const double whole = std::floor(motion.du);
  const float t = static_cast<float>(motion.du - whole);
  for (int j = 0; j <= L; ++j)
    s.weights[j] = (1.0f - t) * (j < L ? taper_[j] : 0.0f) + t * (j > 0 ? taper_[j - 1] : 0.0f);
  // Rows the fit can reach: |ln s| <= kMaxLogScale moves the window's ends by at most
  // 0.11 L, dv' stays near dv.
  const int margin = L / 4 + 3 + static_cast<int>(std::ceil(std::abs(motion.dv)));
  const int v_lo = std::max(0, top_ - margin), v_hi = std::min(height_ - 1, top_ + L - 1 + margin);
  std::fill(s.reference_ok.begin(), s.reference_ok.end(), 0);
  profile(reference, v_lo, v_hi - v_lo + 1, first + static_cast<int>(whole), s.weights.data(),
          L + 1, s.reference.data() + v_lo, s.reference_ok.data() + v_lo, s.sums.data());

  // r at row v (linear between rows) and its slope (central differences, linear between rows).
  const auto sample = [&](double v, double& value, double& slope) {
    if (!(v >= 1.0 && v < height_ - 2.0)) return false;
    const int i = static_cast<int>(v);  // v >= 1: truncation is the floor
    const double floor_v = i;
    if (!s.reference_ok[i - 1] || !s.reference_ok[i] || !s.reference_ok[i + 1] ||
        !s.reference_ok[i + 2])
      return false;
    const double f = v - floor_v;
    const std::vector<double>& r = s.reference;
    value = (1.0 - f) * r[i] + f * r[i + 1];
    slope = 0.5 * ((r[i + 1] - r[i - 1]) * (1.0 - f) + (r[i + 2] - r[i]) * f);
    return true;
  };

  const double yc = 0.5 * (L - 1), vc = top_ + yc;
  double log_s = 0.0, shift = motion.dv, gain = 1.0, offset = 0.0;
  double residual2 = 0.0, sampled = 0.0;
  Eigen::Matrix4d N = Eigen::Matrix4d::Zero();
  for (int iteration = 0; iteration < kMaxIterations; ++iteration) {
    // The normal equations' upper triangle and right-hand side, accumulated as scalars.
    double n00 = 0, n01 = 0, n02 = 0, n03 = 0, n11 = 0, n12 = 0, n13 = 0, n22 = 0, n23 = 0,
           n33 = 0, g0 = 0, g1 = 0, g2 = 0, g3 = 0;
    residual2 = 0.0;
    sampled = 0.0;
    const double scale = std::exp(log_s);
    for (int y = 0; y < L; ++y) {
      if (!s.current_ok[y]) continue;
      const double yy = y - yc;
      double p = 0.0, slope = 0.0;
      if (!sample(vc + shift + scale * yy, p, slope)) continue;
      const double w = taper_[y];
      const double r = s.current[y] - (gain * p + offset);
      // d(model)/d(ln s, dv', gain, offset).
      const double d = gain * slope * scale;
      const double j0 = d * yy, j1 = gain * slope, j2 = p;
      const double wj0 = w * j0, wj1 = w * j1, wj2 = w * j2;
      n00 += wj0 * j0;
      n01 += wj0 * j1;
      n02 += wj0 * j2;
      n03 += wj0;
      n11 += wj1 * j1;
      n12 += wj1 * j2;
      n13 += wj1;
      n22 += wj2 * j2;
      n23 += wj2;
      n33 += w;
      g0 += wj0 * r;
      g1 += wj1 * r;
      g2 += wj2 * r;
      g3 += w * r;
      residual2 += w * r * r;
    }
    sampled = n33;
    if (!(sampled > 0.0)) return false;
    N << n00, n01, n02, n03, n01, n11, n12, n13, n02, n12, n22, n23, n03, n13, n23, n33;
    const Eigen::LDLT<Eigen::Matrix4d> ldlt(N);
    const Eigen::Vector4d step = ldlt.solve(Eigen::Vector4d(g0, g1, g2, g3));
    if (ldlt.info() != Eigen::Success || !step.allFinite()) return false;
    log_s += step(0);
    shift += step(1);
    gain += step(2);
    offset += step(3);
    if (std::abs(step(0)) < kLogScaleTolerance && std::abs(step(1)) < kShiftTolerancePx) break;
  }
  if (!(sampled >= kMinSampleWeight * taper_sum_) || !std::isfinite(log_s) ||
      std::abs(log_s) > kMaxLogScale)
    return false;
  // The last step's normal matrix (the step only refines the solution it describes).
  const double variance_factor = N.inverse()(0, 0);
  const double sigma = std::sqrt(std::max(variance_factor * residual2 / sampled, 0.0));
  if (!(sigma > 0.0) || !std::isfinite(sigma)) return false;
  motion.vertical_scale = std::exp(log_s);
  motion.vertical_scale_sigma = sigma;
  return true;
}

void VerticalScale::measure(const cv::Mat& reference, const cv::Mat& current,
                            std::span<WindowMotion> windows, runtime::WorkerPool& pool) const {
  for (WindowMotion& m : windows) {
    m.vertical_scale = 1.0;
    m.vertical_scale_sigma = 0.0;
  }
  const cv::Size size(width_, height_);
  if (reference.size() != size || current.size() != size || reference.type() != CV_32FC1 ||
      current.type() != CV_32FC1 || windows.size() != centers_.size())
    return;
  auto one = [&](int worker, int k) {
    WindowMotion& m = windows[static_cast<std::size_t>(k)];
    if (!m.valid || !(m.confidence > 0.0) || !(m.rs_confidence > 0.0) ||
        !(std::abs(m.du) < width_) || !(std::abs(m.dv) < height_))
      return;
    const int first =
        static_cast<int>(std::lround(centers_[static_cast<std::size_t>(k)] - 0.5 * (window_ - 1)));
    (void)measureWindow(first, reference, current, m, scratch_[static_cast<std::size_t>(worker)]);
  };
  const int n = static_cast<int>(windows.size());
  if (pool.size() > static_cast<int>(scratch_.size())) {
    for (int k = 0; k < n; ++k) one(0, k);
    return;
  }
  pool.run(n, one);
}

}  // namespace omnipose::pipeline
