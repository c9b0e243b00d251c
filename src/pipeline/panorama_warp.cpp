#include "pipeline/panorama_warp.hpp"

#include <algorithm>
#include <cmath>

#include "image/cubic_kernel.hpp"
#include "runtime/simd.hpp"

namespace omnipose {
// Image sampling: Keys cubic convolution, a = -0.75 (image/cubic_kernel.hpp says why).

PanoramaWarp::PanoramaWarp(const PanoramaGeometry& geometry) : geometry_(geometry) {
  grid_cols_ = geometry.width / kGridStep + 2;
  grid_rows_ = (geometry.height - 1) / kGridStep + 2;
  grid_du_.resize(static_cast<std::size_t>(grid_cols_) * grid_rows_);
  grid_dv_.resize(grid_du_.size());
  padded_.create(geometry.height + 2 * kPadRows, geometry.width + 2 * kPad, CV_32FC1);
  for (int gx = 0; gx < grid_cols_; ++gx) {
    const double theta = geometry.azimuth(gx * kGridStep);
    grid_cos_.push_back(std::cos(theta));
    grid_sin_.push_back(std::sin(theta));
  }
  for (int gy = 0; gy < grid_rows_; ++gy) grid_h_.push_back(geometry.cylinderHeight(gy * kGridStep));
}

Eigen::Vector2d PanoramaWarp::displacement(const Eigen::Matrix3d& Rt, double cos_theta,
                                           double sin_theta, double h, double v) const {
  // X_prev on the unit cylinder -> X_cur = R^T X. The azimuth change is the angle from
  // (cos theta, sin theta) to Y's horizontal part: atan2 of their cross and dot products,
  // already in (-pi, pi].
  const Eigen::Vector3d Y = Rt * Eigen::Vector3d(cos_theta, sin_theta, h);
  const double dot = cos_theta * Y.x() + sin_theta * Y.y();
  const double cross = cos_theta * Y.y() - sin_theta * Y.x();
  const double rho = std::sqrt(Y.x() * Y.x() + Y.y() * Y.y());
  const double h_cur = rho > 1e-9 ? Y.z() / rho : 0.0;
  return {std::atan2(cross, dot) / geometry_.gamma(), geometry_.row(h_cur) - v};
}

Eigen::Vector2d PanoramaWarp::displacementAt(const Eigen::Matrix3d& R, double u, double v) const {
  const double theta = geometry_.azimuth(u);
  return displacement(R.transpose(), std::cos(theta), std::sin(theta),
                      geometry_.cylinderHeight(v), v);
}

Eigen::Vector2f PanoramaWarp::gridDisplacement(int u, int v) const {
  const int gx = u / kGridStep, gy = v / kGridStep;
  const float fx = static_cast<float>(u - gx * kGridStep) / kGridStep;
  const float fy = static_cast<float>(v - gy * kGridStep) / kGridStep;
  const std::size_t i0 = static_cast<std::size_t>(gy) * grid_cols_ + gx, i1 = i0 + grid_cols_;
  const auto at = [&](const std::vector<float>& g) {
    return (1.0f - fy) * ((1.0f - fx) * g[i0] + fx * g[i0 + 1]) +
           fy * ((1.0f - fx) * g[i1] + fx * g[i1 + 1]);
  };
  return {at(grid_du_), at(grid_dv_)};
}

std::pair<float, float> PanoramaWarp::rowDisplacementRange(int v) const {
  const std::size_t first = static_cast<std::size_t>(v / kGridStep) * grid_cols_;
  const auto begin = grid_dv_.begin() + static_cast<std::ptrdiff_t>(first);
  const auto [lo, hi] = std::minmax_element(begin, begin + 2 * grid_cols_);
  return {*lo, *hi};
}

void PanoramaWarp::projectGridRows(const Eigen::Matrix3d& R, int first, int last) {
  const Eigen::Matrix3d Rt = R.transpose();
  for (int gy = first; gy < last; ++gy) {
    const double v = gy * kGridStep;
    for (int gx = 0; gx < grid_cols_; ++gx) {
      const Eigen::Vector2d d = displacement(Rt, grid_cos_[gx], grid_sin_[gx], grid_h_[gy], v);
      const std::size_t i = static_cast<std::size_t>(gy) * grid_cols_ + gx;
      grid_du_[i] = static_cast<float>(d.x());
      grid_dv_[i] = static_cast<float>(d.y());
    }
  }
}

void PanoramaWarp::padCurrent(const cv::Mat& current) {
  const int W = geometry_.width, H = geometry_.height;
  current.copyTo(padded_(cv::Rect(kPad, kPadRows, W, H)));
  current(cv::Rect(W - kPad, 0, kPad, H)).copyTo(padded_(cv::Rect(0, kPadRows, kPad, H)));
  current(cv::Rect(0, 0, kPad, H)).copyTo(padded_(cv::Rect(W + kPad, kPadRows, kPad, H)));
  // Rows beyond the edges repeat the edge rows (wrapped columns included).
  for (int i = 0; i < kPadRows; ++i) {
    padded_.row(kPadRows).copyTo(padded_.row(i));
    padded_.row(kPadRows + H - 1).copyTo(padded_.row(kPadRows + H + i));
  }
}

OMNIPOSE_SIMD_CLONES
void PanoramaWarp::derotateRows(cv::Mat& out, int first, int last) const {
  const int W = geometry_.width, H = geometry_.height;
  // Bilinear interpolation of the (smooth) displacement; bicubic sampling of the image
  // (a = -0.75): the sampler's phase response must be linear, or the residual shifts are
  // biased by the fractional part of the motion. Four pixels at a time: the 4 columns of one
  // grid cell share their grid corners; per pixel the 4 x 4 taps are four row vectors
  // weighted by the row weights, then by the column weights.
  namespace simd = runtime::simd;
  static_assert(kGridStep == 4, "one grid cell = one group of four lanes");
  const int PW = padded_.cols;
  const simd::F4 fx{0.0f, 0.25f, 0.5f, 0.75f};
  const simd::F4 one = simd::broadcast(1.0f);
  const simd::F4 x_lo = simd::broadcast(1.0f), x_hi = simd::broadcast(static_cast<float>(PW - 2.001f));
  const simd::F4 lane{0.0f, 1.0f, 2.0f, 3.0f};
  const simd::F4 y_lo = simd::broadcast(-2.0f), y_hi = simd::broadcast(static_cast<float>(H));
  const float* origin = padded_.ptr<float>(0);
  const std::ptrdiff_t stride = static_cast<std::ptrdiff_t>(padded_.step1());
  for (int v = first; v < last; ++v) {
    const int gy = v / kGridStep;
    const float fy = static_cast<float>(v - gy * kGridStep) / kGridStep;
    const float* du0 = &grid_du_[static_cast<std::size_t>(gy) * grid_cols_];
    const float* du1 = du0 + grid_cols_;
    const float* dv0 = &grid_dv_[static_cast<std::size_t>(gy) * grid_cols_];
    const float* dv1 = dv0 + grid_cols_;
    float* dst = out.ptr<float>(v);
    const simd::F4 fy4 = simd::broadcast(fy), gy4 = simd::broadcast(1.0f - fy);
    for (int u = 0; u < W; u += kGridStep) {
      const int gx = u / kGridStep;
      // Displacement at the 4 columns of this cell (bilinear in the grid).
      const simd::F4 du = gy4 * ((one - fx) * du0[gx] + fx * du0[gx + 1]) +
                          fy4 * ((one - fx) * du1[gx] + fx * du1[gx + 1]);
      const simd::F4 dv = gy4 * ((one - fx) * dv0[gx] + fx * dv0[gx + 1]) +
                          fy4 * ((one - fx) * dv1[gx] + fx * dv1[gx + 1]);
      const simd::F4 x = simd::min(simd::max(simd::broadcast(static_cast<float>(u + kPad)) + lane + du, x_lo), x_hi);
      // Rows beyond the edges replicate the edge rows: with y clamped to [-2, H] every tap
      // (rows floor(y) - 1 .. floor(y) + 2) is inside the padded image (row offset
      // kPadRows), and a y further out reads the edge row four times, as it would unclamped.
      const simd::F4 y = simd::min(simd::max(simd::broadcast(static_cast<float>(v)) + dv, y_lo), y_hi);
      const simd::I4 x0 = __builtin_convertvector(x, simd::I4);  // x >= 1: truncation = floor
      const simd::I4 y0 = simd::floorToInt(y);
      const simd::F4 y_floor = __builtin_convertvector(y0, simd::F4);
      simd::F4 wx[4], wy[4];
      image::keysCubicWeights(x - __builtin_convertvector(x0, simd::F4), wx);
      image::keysCubicWeights(y - y_floor, wy);
      // Per lane l, acc[l][t] = column tap t weighted over the rows; the four lanes'
      // accumulators are transposed so that the column weights apply lane-wise:
      // out[l] = (acc[l][0] wx0 + acc[l][1] wx1) + (acc[l][2] wx2 + acc[l][3] wx3), the
      // same operations in the same order as a per-lane dot product. Lanes past the last
      // column (W % 4 != 0) read clamped, valid pixels and are not stored.
      const auto taps = [&]<int l>() {
        const float* r0 = origin + (y0[l] + (kPadRows - 1)) * stride + (x0[l] - 1);
        return simd::splat<l>(wy[0]) * simd::load(r0) + simd::splat<l>(wy[1]) * simd::load(r0 + stride) +
               simd::splat<l>(wy[2]) * simd::load(r0 + 2 * stride) +
               simd::splat<l>(wy[3]) * simd::load(r0 + 3 * stride);
      };
      simd::F4 acc[4] = {taps.template operator()<0>(), taps.template operator()<1>(),
                         taps.template operator()<2>(), taps.template operator()<3>()};
      simd::transpose(acc[0], acc[1], acc[2], acc[3]);
      const simd::F4 sum4 = (acc[0] * wx[0] + acc[1] * wx[1]) + (acc[2] * wx[2] + acc[3] * wx[3]);
      if (u + 4 <= W) {
        simd::store(dst + u, sum4);
      } else {
        for (int l = 0; u + l < W; ++l) dst[u + l] = sum4[l];
      }
    }
  }
}

}  // namespace omnipose
