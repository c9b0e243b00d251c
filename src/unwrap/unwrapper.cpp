#include "omnipose/unwrapper.hpp"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>

#include "common/problem_list.hpp"
#include "runtime/simd.hpp"

namespace omnipose {

std::vector<std::string> Unwrapper::Options::validate() const {
  std::vector<std::string> problems;
  detail::checkRange(problems, "min_mean_intensity", min_mean_intensity, 0.0, 254.0,
                     " grey levels");
  return problems;
}

Unwrapper::Unwrapper(const Calibration& calibration, const Options& options)
    : calibration_(calibration), options_(options) {
  {
    std::vector<std::string> problems = options.validate();
    for (const auto& p : calibration.validate()) problems.push_back("calibration: " + p);
    detail::throwIfProblems("Unwrapper", problems);
  }

  const int W = calibration.panorama.width, H = calibration.panorama.height;
  validity_.create(H, W, CV_32FC1);
  validity_.setTo(1.0f);
  if (options.input == InputKind::kOmni) buildTable(calibration);
  grey_.create(inputSize(), CV_8UC1);
}

namespace {

/// Omni pixels between the centres of neighbouring panorama pixels along u and along v,
/// the largest over row v (0 where the lens model has no bearing there).
std::pair<double, double> rowDensity(const Calibration& calibration, int v) {
  double along_u = 0.0, along_v = 0.0;
  for (int u = 0; u < calibration.panorama.width; ++u) {
    const Eigen::Vector2d du = calibration.omniPixel(u + 0.5, v) - calibration.omniPixel(u - 0.5, v);
    const Eigen::Vector2d dv = calibration.omniPixel(u, v + 0.5) - calibration.omniPixel(u, v - 0.5);
    if (du.allFinite()) along_u = std::max(along_u, du.norm());
    if (dv.allFinite()) along_v = std::max(along_v, dv.norm());
  }
  return {along_u, along_v};
}

}  // namespace

int Unwrapper::samplesAlong(double density) {
  return std::clamp(static_cast<int>(std::floor(density)), 1, kMaxSamplesPerAxis);
}

void Unwrapper::buildTable(const Calibration& calibration) {
  const int W = calibration.panorama.width, H = calibration.panorama.height;
  const int iw = calibration.omni.image_width, ih = calibration.omni.image_height;
  const cv::Mat& mask = calibration.omni.mask;
  row_start_.resize(static_cast<std::size_t>(H) + 1);
  row_samples_u_.resize(H);
  row_samples_v_.resize(H);
  std::size_t entries = 0;
  for (int v = 0; v < H; ++v) {
    const auto [along_u, along_v] = rowDensity(calibration, v);
    row_samples_u_[v] = samplesAlong(along_u);
    row_samples_v_[v] = samplesAlong(along_v);
    row_start_[v] = entries;
    entries += static_cast<std::size_t>(W) * row_samples_u_[v] * row_samples_v_[v];
  }
  row_start_[H] = entries;
  offset_.assign(entries, kOutside);
  frac_x_.assign(entries, 0.0f);
  frac_y_.assign(entries, 0.0f);
  for (int v = 0; v < H; ++v) {
    const int su = row_samples_u_[v], sv = row_samples_v_[v];
    for (int u = 0; u < W; ++u) {
      // The pixel's samples on a regular su x sv grid over its footprint; all of them inside
      // the image and unmasked, or the pixel is black and unusable.
      bool inside = true, masked = false;
      for (int k = 0; k < su * sv && inside; ++k) {
        const double pu = u + (k % su + 0.5) / su - 0.5, pv = v + (k / su + 0.5) / sv - 0.5;
        const Eigen::Vector2d p = calibration.omniPixel(pu, pv);
        // Outside the image (or no bearing in the lens model): decided in double, before any
        // conversion to int.
        const double fx = std::floor(p.x()), fy = std::floor(p.y());
        inside = p.allFinite() && fx >= 0 && fy >= 0 && fx + 1 < iw && fy + 1 < ih;
        if (!inside) break;
        const int x0 = static_cast<int>(fx), y0 = static_cast<int>(fy);
        const float ax = static_cast<float>(p.x() - fx), ay = static_cast<float>(p.y() - fy);
        const std::size_t i = row_start_[v] + static_cast<std::size_t>(k) * W + u;
        offset_[i] = y0 * iw + x0;
        frac_x_[i] = ax;
        frac_y_[i] = ay;
        // Masked: any tap of the bilinear footprint that carries weight is masked.
        if (!mask.empty()) {
          const uint8_t* m0 = mask.ptr<uint8_t>(y0) + x0;
          const uint8_t* m1 = mask.ptr<uint8_t>(y0 + 1) + x0;
          const bool right = ax > 0, below = ay > 0;
          if (m0[0] == 0 || (right && m0[1] == 0) || (below && m1[0] == 0) ||
              (right && below && m1[1] == 0))
            masked = true;
        }
      }
      if (!inside) {
        for (int k = 0; k < su * sv; ++k) {
          const std::size_t i = row_start_[v] + static_cast<std::size_t>(k) * W + u;
          offset_[i] = kOutside;  // outside the image or the lens model: black, unusable
          frac_x_[i] = frac_y_[i] = 0.0f;
        }
      }
      if (!inside || masked) validity_.at<float>(v, u) = 0.0f;
    }
  }
}

cv::Size inputFrameSize(const Calibration& calibration, InputKind input) {
  if (input == InputKind::kPanorama) return calibration.panorama.size();
  return {calibration.omni.image_width, calibration.omni.image_height};
}

cv::Size Unwrapper::inputSize() const { return inputFrameSize(calibration_, options_.input); }

cv::Size Unwrapper::panoramaSize() const {
  return calibration_.panorama.size();
}

double Unwrapper::usableFraction() const {
  return cv::mean(validity_)[0];
}

cv::Mat Unwrapper::makePanorama() const { return cv::Mat(panoramaSize(), CV_32FC1, 0.0f); }

Expected<void> Unwrapper::unwrap(const cv::Mat& frame, cv::Mat& panorama) {
  const auto grey = toGrey(frame);
  if (!grey) return std::unexpected(grey.error());
  if (panorama.size() != panoramaSize() || panorama.type() != CV_32FC1) {
    return fail(ErrorCode::kInvalidArgument, "panorama buffer must be CV_32FC1 %dx%d",
                panoramaSize().width, panoramaSize().height);
  }
  unwrapRows(**grey, panorama, 0, panorama.rows);
  return {};
}

Expected<const cv::Mat*> Unwrapper::toGrey(const cv::Mat& frame) {
  const cv::Size want = inputSize();
  if (frame.empty()) return fail(ErrorCode::kBadFrame, "empty frame");
  if (frame.size() != want) {
    return fail(ErrorCode::kBadFrame, "frame is %dx%d, expected %dx%d", frame.cols, frame.rows,
                want.width, want.height);
  }
  if (frame.depth() != CV_8U || (frame.channels() != 1 && frame.channels() != 3 &&
                                 frame.channels() != 4)) {
    return fail(ErrorCode::kBadFrame, "frame has type %d, expected 8-bit grey, BGR or BGRA",
                frame.type());
  }
  // Colour -> grey into the preallocated buffer (no allocation: grey_ has the size).
  const cv::Mat* grey = &frame;
  if (frame.channels() != 1) {
    cv::cvtColor(frame, grey_, frame.channels() == 3 ? cv::COLOR_BGR2GRAY : cv::COLOR_BGRA2GRAY);
    grey = &grey_;
  }
  if (cv::mean(*grey)[0] < options_.min_mean_intensity) {
    return fail(ErrorCode::kBadFrame, "frame is black (mean grey level below %.1f)",
                options_.min_mean_intensity);
  }
  // The lookup's offsets assume a continuous image: copy ROI views (grey_ has the size).
  if (options_.input == InputKind::kOmni && !grey->isContinuous()) {
    grey->copyTo(grey_);
    grey = &grey_;
  }
  return grey;
}

OMNIPOSE_SIMD_CLONES
void Unwrapper::unwrapRows(const cv::Mat& grey, cv::Mat& panorama, int first, int last) const {
  if (options_.input == InputKind::kPanorama) {
    cv::Mat band = panorama.rowRange(first, last);  // a view: convertTo writes in place
    grey.rowRange(first, last).convertTo(band, CV_32F);
    return;
  }
  // Bilinear lookup through the precomputed table: a = p00 + ax (p01 - p00), b likewise on
  // the row below, a + ay (b - a); four pixels at a time, the same operations per pixel in
  // the last W % 4.
  namespace simd = runtime::simd;
  const int W = panorama.cols;
  const std::size_t stride = static_cast<std::size_t>(grey.cols);  // continuous (toGrey())
  const uint8_t* src = grey.ptr<uint8_t>(0);
  const simd::I4 outside = {kOutside, kOutside, kOutside, kOutside};
  for (int v = first; v < last; ++v) {
    float* dst = panorama.ptr<float>(v);
    const int samples = row_samples_u_[v] * row_samples_v_[v];
    const float weight = 1.0f / static_cast<float>(samples);  // 1 exactly for one sample
    const simd::F4 weights = {weight, weight, weight, weight};
    int u = 0;
    for (; u + 4 <= W; u += 4) {
      simd::F4 sum = {0.0f, 0.0f, 0.0f, 0.0f};
      for (int k = 0; k < samples; ++k) {
        const std::size_t at = row_start_[v] + static_cast<std::size_t>(k) * W + u;
        simd::I4 off;
        std::memcpy(&off, offset_.data() + at, sizeof off);
        const simd::I4 inside = off != outside;  // -1 where the pixel has a footprint
        off &= inside;                            // black pixels read pixel 0, then are cleared
        const uint8_t* p0 = src + off[0];
        const uint8_t* p1 = src + off[1];
        const uint8_t* p2 = src + off[2];
        const uint8_t* p3 = src + off[3];
        const simd::I4 i00{p0[0], p1[0], p2[0], p3[0]}, i01{p0[1], p1[1], p2[1], p3[1]};
        const simd::I4 i10{p0[stride], p1[stride], p2[stride], p3[stride]};
        const simd::I4 i11{p0[stride + 1], p1[stride + 1], p2[stride + 1], p3[stride + 1]};
        const simd::F4 p00 = __builtin_convertvector(i00, simd::F4);
        const simd::F4 p01 = __builtin_convertvector(i01, simd::F4);
        const simd::F4 p10 = __builtin_convertvector(i10, simd::F4);
        const simd::F4 p11 = __builtin_convertvector(i11, simd::F4);
        const simd::F4 fx = simd::load(frac_x_.data() + at), fy = simd::load(frac_y_.data() + at);
        const simd::F4 a = p00 + fx * (p01 - p00), b = p10 + fx * (p11 - p10);
        const simd::F4 out = a + fy * (b - a);
        sum += reinterpret_cast<simd::F4>(reinterpret_cast<simd::I4>(out) & inside);
      }
      simd::store(dst + u, sum * weights);
    }
    for (; u < W; ++u) {
      float sum = 0.0f;
      for (int k = 0; k < samples; ++k) {
        const std::size_t at = row_start_[v] + static_cast<std::size_t>(k) * W + u;
        if (offset_[at] == kOutside) continue;
        const uint8_t* p = src + offset_[at];
        const float p00 = p[0], p01 = p[1], p10 = p[stride], p11 = p[stride + 1];
        const float a = p00 + frac_x_[at] * (p01 - p00), b = p10 + frac_x_[at] * (p11 - p10);
        sum += a + frac_y_[at] * (b - a);
      }
      dst[u] = sum * weight;
    }
  }
}

}  // namespace omnipose
