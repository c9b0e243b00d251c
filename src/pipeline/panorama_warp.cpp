#include "pipeline/panorama_warp.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>

namespace omnipose {
namespace {

/// Cubic convolution weights (Keys kernel with a = -0.75, OpenCV's INTER_CUBIC) for the
/// 4 taps at -1, 0, 1, 2 of offset t in [0, 1). Of the cubic kernels this one has the
/// most linear phase: a = -0.5 leaves a shift bias of about 0.03 px after resampling,
/// which phase correlation reads as motion (docs/results/experiments/resample_bias.cpp).
inline void cubicWeights(float t, float w[4]) {
  constexpr float a = -0.75f;
  auto near = [](float x) { return ((a + 2) * x - (a + 3)) * x * x + 1; };        // |x| <= 1
  auto far = [](float x) { return ((a * x - 5 * a) * x + 8 * a) * x - 4 * a; };  // 1 < |x| < 2
  w[0] = far(1 + t);
  w[1] = near(t);
  w[2] = near(1 - t);
  w[3] = far(2 - t);
}

}  // namespace

PanoramaWarp::PanoramaWarp(const PanoramaGeometry& geometry) : geometry_(geometry) {
  grid_cols_ = geometry.width / kGridStep + 2;
  grid_rows_ = (geometry.height - 1) / kGridStep + 2;
  grid_du_.resize(static_cast<std::size_t>(grid_cols_) * grid_rows_);
  grid_dv_.resize(grid_du_.size());
  padded_.create(geometry.height, geometry.width + 2 * kPad, CV_32FC1);
}

void PanoramaWarp::derotate(const cv::Mat& current, const Eigen::Matrix3d& R, cv::Mat& out) {
  prepare(current, R);
  derotateRows(out, 0, geometry_.height);
}

void PanoramaWarp::prepare(const cv::Mat& current, const Eigen::Matrix3d& R) {
  const int W = geometry_.width, H = geometry_.height;
  const double gamma = geometry_.gamma();
  const Eigen::Matrix3d Rt = R.transpose();

  // Exact displacement on the grid: X_prev on the unit cylinder -> X_cur = R^T X.
  for (int gy = 0; gy < grid_rows_; ++gy) {
    const double v = gy * kGridStep;
    const double h = geometry_.cylinderHeight(v);
    for (int gx = 0; gx < grid_cols_; ++gx) {
      const double u = gx * kGridStep;
      const double theta = geometry_.azimuth(u);
      const Eigen::Vector3d X(std::cos(theta), std::sin(theta), h);
      const Eigen::Vector3d Y = Rt * X;
      const double rho = std::hypot(Y.x(), Y.y());
      // Azimuth change relative to theta, wrapped to (-pi, pi].
      double dtheta = std::atan2(Y.y(), Y.x()) - theta;
      dtheta = std::remainder(dtheta, 2.0 * std::numbers::pi);
      const double h_cur = rho > 1e-9 ? Y.z() / rho : 0.0;
      const std::size_t i = static_cast<std::size_t>(gy) * grid_cols_ + gx;
      grid_du_[i] = static_cast<float>(dtheta / gamma);
      grid_dv_[i] = static_cast<float>(geometry_.row(h_cur) - v);
    }
  }

  // Wrapped copy of the current panorama so that u needs no modulo per pixel.
  current.copyTo(padded_(cv::Rect(kPad, 0, W, H)));
  current(cv::Rect(W - kPad, 0, kPad, H)).copyTo(padded_(cv::Rect(0, 0, kPad, H)));
  current(cv::Rect(0, 0, kPad, H)).copyTo(padded_(cv::Rect(W + kPad, 0, kPad, H)));
}

void PanoramaWarp::derotateRows(cv::Mat& out, int first, int last) const {
  const int W = geometry_.width, H = geometry_.height;
  // Bilinear interpolation of the (smooth) displacement; bicubic sampling of the image
  // (a = -0.75): the sampler's phase response must be linear, or the residual shifts are
  // biased by the fractional part of the motion.
  const int PW = padded_.cols;
  for (int v = first; v < last; ++v) {
    const int gy = v / kGridStep;
    const float fy = static_cast<float>(v - gy * kGridStep) / kGridStep;
    const float* du0 = &grid_du_[static_cast<std::size_t>(gy) * grid_cols_];
    const float* du1 = du0 + grid_cols_;
    const float* dv0 = &grid_dv_[static_cast<std::size_t>(gy) * grid_cols_];
    const float* dv1 = dv0 + grid_cols_;
    float* dst = out.ptr<float>(v);
    for (int u = 0; u < W; ++u) {
      const int gx = u / kGridStep;
      const float fx = static_cast<float>(u - gx * kGridStep) / kGridStep;
      const float du = (1 - fy) * ((1 - fx) * du0[gx] + fx * du0[gx + 1]) +
                       fy * ((1 - fx) * du1[gx] + fx * du1[gx + 1]);
      const float dv = (1 - fy) * ((1 - fx) * dv0[gx] + fx * dv0[gx + 1]) +
                       fy * ((1 - fx) * dv1[gx] + fx * dv1[gx + 1]);
      const float x = std::clamp(u + du + kPad, 1.0f, static_cast<float>(PW - 2.001f));
      const float y = v + dv;
      const int x0 = static_cast<int>(x);
      const int y0 = static_cast<int>(std::floor(y));
      float wx[4], wy[4];
      cubicWeights(x - x0, wx);
      cubicWeights(y - y0, wy);
      float sum = 0.0f;
      for (int j = 0; j < 4; ++j) {
        const int row = std::clamp(y0 - 1 + j, 0, H - 1);  // rows beyond the edge: replicate
        const float* p = padded_.ptr<float>(row) + x0 - 1;
        sum += wy[j] * (wx[0] * p[0] + wx[1] * p[1] + wx[2] * p[2] + wx[3] * p[3]);
      }
      dst[u] = sum;
    }
  }
}

}  // namespace omnipose
