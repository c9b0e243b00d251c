#include "registration/log_polar.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <stdexcept>

#include "runtime/simd.hpp"

namespace omnipose::registration {

namespace simd = runtime::simd;
namespace {

/// Fraction of the log-radius axis covered by a cosine ramp at each end (Tukey taper).
constexpr double kTaperRamp = 0.25;

/// High-pass emphasis H(k) = 1 - cos^2(pi rho), rho = |k| / n cycles/sample, 1 for rho >= 1/2.
double highPass(int ku, int kv, int n) {
  const double rho = std::min(std::hypot(ku, kv) / n, 0.5);
  const double c = std::cos(std::numbers::pi * rho);
  return 1.0 - c * c;
}

/// Tukey taper over [0, count): cosine ramps of kTaperRamp * count at both ends.
float tukey(int b, int count) {
  const double t = (b + 0.5) / count;
  const double edge = std::min(t, 1.0 - t);
  if (edge >= kTaperRamp) return 1.0f;
  return static_cast<float>(0.5 - 0.5 * std::cos(std::numbers::pi * edge / kTaperRamp));
}

/// Cubic B-spline weights of the taps floor(x) - 1 .. floor(x) + 2 at position x.
void cubicBSpline(double x, int& first, float* w) {
  const double x0 = std::floor(x), f = x - x0;
  first = static_cast<int>(x0) - 1;
  w[0] = static_cast<float>((1 - f) * (1 - f) * (1 - f) / 6);
  w[1] = static_cast<float>((3 * f * f * f - 6 * f * f + 4) / 6);
  w[2] = static_cast<float>((-3 * f * f * f + 3 * f * f + 3 * f + 1) / 6);
  w[3] = static_cast<float>(f * f * f / 6);
}

}  // namespace

LogPolarMap::LogPolarMap(int n, int n_theta, int n_radius, double r_min, double r_max)
    : n_(n),
      n_theta_(n_theta),
      n_radius_(n_radius),
      angle_step_(std::numbers::pi / n_theta),
      log_radius_step_(std::log(r_max / r_min) / (n_radius - 1)),
      reach_(static_cast<int>(std::ceil(r_max)) + 2),
      grid_cols_(reach_ + 2),
      taper_(n_radius),
      column_mean_(n_radius),
      column_gain_(n_radius) {
  if (n % 2 != 0 || n_theta < 4 || n_radius < 4 || !(r_min > 0.0) || !(r_max > r_min) ||
      r_max > n / 2 - 3)
    throw std::invalid_argument("LogPolarMap: bad sizes or radii");
  // Extended grid: entry (row, col) is frequency (k_u, k_v) = (col - 1, row - reach).
  const int rows = 2 * reach_ + 1;
  grid_.assign(static_cast<std::size_t>(rows) * grid_cols_, 0.0f);
  high_pass_.resize(grid_.size());
  for (int row = 0; row < rows; ++row)
    for (int col = 0; col < grid_cols_; ++col)
      high_pass_[static_cast<std::size_t>(row) * grid_cols_ + col] =
          static_cast<float>(highPass(col - 1, row - reach_, n));
  // Taps and separable weights of every output sample.
  const std::size_t samples = static_cast<std::size_t>(n_theta) * n_radius;
  tap_offset_.resize(samples);
  weight_u_.resize(4 * samples);
  weight_v_.resize(4 * samples);
  for (int a = 0; a < n_theta; ++a) {
    const double alpha = -std::numbers::pi / 2 + a * angle_step_;
    for (int b = 0; b < n_radius; ++b) {
      const double rho = r_min * std::exp(b * log_radius_step_);
      const std::size_t i = static_cast<std::size_t>(a) * n_radius + b;
      int first_u = 0, first_v = 0;
      cubicBSpline(rho * std::cos(alpha), first_u, &weight_u_[4 * i]);
      cubicBSpline(rho * std::sin(alpha), first_v, &weight_v_[4 * i]);
      tap_offset_[i] = (first_v + reach_) * grid_cols_ + (first_u + 1);
    }
  }
  // Grid columns the taps read, per row: fillGrid() computes no others.
  row_columns_.assign(rows, 0);
  for (const int offset : tap_offset_) {
    const int row = offset / grid_cols_, last_col = offset % grid_cols_ + 3;
    for (int t = 0; t < 4; ++t) row_columns_[row + t] = std::max(row_columns_[row + t], last_col + 1);
  }
  // resample() interpolates four samples of a row at once: store their u weights tap-major
  // (weight_u_[4 i0 + 4 t + l] = weight t of sample i0 + l); a row's last n_radius % 4
  // samples keep theirs sample-major.
  for (int a = 0; a < n_theta; ++a) {
    for (int b = 0; b + 4 <= n_radius; b += 4) {
      float* w = &weight_u_[4 * (static_cast<std::size_t>(a) * n_radius + b)];
      simd::F4 t0 = simd::load(w), t1 = simd::load(w + 4), t2 = simd::load(w + 8),
               t3 = simd::load(w + 12);
      simd::transpose(t0, t1, t2, t3);
      simd::store(w, t0);
      simd::store(w + 4, t1);
      simd::store(w + 8, t2);
      simd::store(w + 12, t3);
    }
  }
  for (int b = 0; b < n_radius; ++b) taper_[b] = tukey(b, n_radius);
}

OMNIPOSE_SIMD_CLONES
void LogPolarMap::fillGrid(const Complex* spectrum) {
  // g = H |F| on the extended grid, row by row, as far as the taps read (row_columns_).
  // Grid row `row` is k_v = row - reach: its columns 1 .. reach + 1 (k_u = 0 .. reach) are
  // the contiguous start of spectrum row k_v mod n, read four bins at a time (the last group
  // may pass the columns read, not the grid); column 0 (k_u = -1) is |F(1, -k_v)|.
  const int rows = 2 * reach_ + 1, half_cols = n_ / 2 + 1;
  for (int row = 0; row < rows; ++row) {
    if (row_columns_[row] == 0) continue;
    const int count = std::min(grid_cols_ - 1, (row_columns_[row] - 1 + 3) / 4 * 4);
    const int kv = row - reach_;
    const Complex* src = spectrum + static_cast<std::size_t>((kv % n_ + n_) % n_) * half_cols;
    const Complex mirrored = spectrum[static_cast<std::size_t>((-kv % n_ + n_) % n_) * half_cols + 1];
    float* g = &grid_[static_cast<std::size_t>(row) * grid_cols_];
    const float* h = &high_pass_[static_cast<std::size_t>(row) * grid_cols_];
    g[0] = h[0] * std::sqrt(std::norm(mirrored));
    const float* z = reinterpret_cast<const float*>(src);
    int c = 0;
    for (; c + 4 <= count; c += 4) {
      const simd::F4 norm = simd::norms(simd::load(z + 2 * c), simd::load(z + 2 * c + 4));
      simd::store(g + 1 + c, simd::load(h + 1 + c) * simd::sqrt(norm));
    }
    for (; c < count; ++c) g[1 + c] = h[1 + c] * std::sqrt(std::norm(src[c]));
  }
}

OMNIPOSE_SIMD_CLONES
double LogPolarMap::resample(const Complex* spectrum, float* out) {
  fillGrid(spectrum);
  // g(a, b) = sum_ij w_v[i] w_u[j] grid(v0 + i, u0 + j): separable cubic B-spline.
  const std::size_t stride = grid_cols_;
  std::fill(column_mean_.begin(), column_mean_.end(), 0.0f);
  std::fill(column_gain_.begin(), column_gain_.end(), 0.0f);
  // Locals: stores through `row` (float) could alias the members, so member access would
  // reload the vectors' pointers and the sizes on every iteration.
  float* const mean_sum = column_mean_.data();
  float* const square_sum = column_gain_.data();
  const float* const grid = grid_.data();
  const int* const tap_offset = tap_offset_.data();
  const float* const weight_v = weight_v_.data();
  const float* const weight_u = weight_u_.data();
  const int n_theta = n_theta_, n_radius = n_radius_;
  // Taps of sample i weighted along v: one row vector of the four u taps.
  const auto vertical = [&](std::size_t i) {
    const float* p = grid + tap_offset[i];
    const float* wv = weight_v + 4 * i;
    return simd::broadcast(wv[0]) * simd::load(p) + simd::broadcast(wv[1]) * simd::load(p + stride) +
           simd::broadcast(wv[2]) * simd::load(p + 2 * stride) +
           simd::broadcast(wv[3]) * simd::load(p + 3 * stride);
  };
  for (int a = 0; a < n_theta; ++a) {
    float* row = out + static_cast<std::size_t>(a) * n_radius;
    const std::size_t first = static_cast<std::size_t>(a) * n_radius;
    int b = 0;
    // Four samples at a time: their tap vectors transposed, the u weights (tap-major)
    // applied lane-wise: (t0 w0 + t1 w1) + (t2 w2 + t3 w3), as a per-sample dot product.
    for (; b + 4 <= n_radius; b += 4) {
      const std::size_t i = first + b;
      simd::F4 t0 = vertical(i), t1 = vertical(i + 1), t2 = vertical(i + 2), t3 = vertical(i + 3);
      simd::transpose(t0, t1, t2, t3);
      const float* wu = weight_u + 4 * i;
      simd::store(row + b, (t0 * simd::load(wu) + t1 * simd::load(wu + 4)) +
                               (t2 * simd::load(wu + 8) + t3 * simd::load(wu + 12)));
    }
    for (; b < n_radius; ++b)
      row[b] = simd::sum(vertical(first + b) * simd::load(weight_u + 4 * (first + b)));
    // Per-radius sums over angle (for the mean and the RMS below).
    b = 0;
    for (; b + 4 <= n_radius; b += 4) {
      const simd::F4 g = simd::load(row + b);
      simd::store(mean_sum + b, simd::load(mean_sum + b) + g);
      simd::store(square_sum + b, simd::load(square_sum + b) + g * g);
    }
    for (; b < n_radius; ++b) {
      mean_sum[b] += row[b];
      square_sum[b] += row[b] * row[b];
    }
  }
  // Per radius: remove the mean over angle, divide by the RMS about it, then taper.
  // The sums become the mean and the gain in place.
  float* const mean = mean_sum;
  float* const gain = square_sum;
  for (int b = 0; b < n_radius; ++b) {
    const float m = mean_sum[b] / n_theta;
    const float var = std::max(square_sum[b] / n_theta - m * m, 0.0f);
    mean[b] = m;
    gain[b] = var > 0.0f ? taper_[b] / std::sqrt(var) : 0.0f;
  }
  // The energy in two running sums (one chain of additions would wait on each one's
  // latency).
  simd::F4 energy4 = simd::broadcast(0.0f), energy4b = simd::broadcast(0.0f);
  double energy = 0.0;
  const auto normalised = [&](float* row, int b) {
    const simd::F4 v = (simd::load(row + b) - simd::load(mean + b)) * simd::load(gain + b);
    simd::store(row + b, v);
    return v * v;
  };
  for (int a = 0; a < n_theta; ++a) {
    float* row = out + static_cast<std::size_t>(a) * n_radius;
    int b = 0;
    for (; b + 8 <= n_radius; b += 8) {
      energy4 += normalised(row, b);
      energy4b += normalised(row, b + 4);
    }
    for (; b + 4 <= n_radius; b += 4) energy4 += normalised(row, b);
    for (; b < n_radius; ++b) {
      row[b] = (row[b] - mean[b]) * gain[b];
      energy += static_cast<double>(row[b]) * row[b];
    }
  }
  return energy + simd::sum(energy4 + energy4b);
}

}  // namespace omnipose::registration
