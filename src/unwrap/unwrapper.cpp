#include "omnipose/unwrapper.hpp"

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>

#include "common/problem_list.hpp"

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
  const int iw = calibration.omni.image_width, ih = calibration.omni.image_height;
  validity_.create(H, W, CV_32FC1);
  validity_.setTo(1.0f);
  if (options.input == InputKind::kOmni) {
    const cv::Mat& mask = calibration.omni.mask;
    offset_.resize(static_cast<std::size_t>(W) * H);
    weight_.resize(offset_.size());
    for (int v = 0; v < H; ++v) {
      for (int u = 0; u < W; ++u) {
        const Eigen::Vector2d p = calibration.omniPixel(u, v);
        const std::size_t i = static_cast<std::size_t>(v) * W + u;
        // Outside the image (or no bearing in the lens model): decided in double, before any
        // conversion to int.
        const double fx = std::floor(p.x()), fy = std::floor(p.y());
        const bool inside = p.allFinite() && fx >= 0 && fy >= 0 && fx + 1 < iw && fy + 1 < ih;
        const int x0 = inside ? static_cast<int>(fx) : 0, y0 = inside ? static_cast<int>(fy) : 0;
        const float ax = static_cast<float>(p.x() - fx), ay = static_cast<float>(p.y() - fy);
        if (!inside) {
          offset_[i] = 0;  // outside the image or the lens model: black, unusable
          weight_[i] = cv::Vec4f(0, 0, 0, 0);
          validity_.at<float>(v, u) = 0.0f;
          continue;
        }
        offset_[i] = y0 * iw + x0;
        weight_[i] = cv::Vec4f((1 - ax) * (1 - ay), ax * (1 - ay), (1 - ax) * ay, ax * ay);
        // Masked: any tap of the bilinear footprint that carries weight is masked.
        if (!mask.empty()) {
          const uint8_t* m0 = mask.ptr<uint8_t>(y0) + x0;
          const uint8_t* m1 = mask.ptr<uint8_t>(y0 + 1) + x0;
          const cv::Vec4f& w = weight_[i];
          if ((w[0] > 0 && m0[0] == 0) || (w[1] > 0 && m0[1] == 0) || (w[2] > 0 && m1[0] == 0) ||
              (w[3] > 0 && m1[1] == 0))
            validity_.at<float>(v, u) = 0.0f;
        }
      }
    }
  }
  grey_.create(inputSize(), CV_8UC1);
}

cv::Size Unwrapper::inputSize() const {
  if (options_.input == InputKind::kPanorama) return panoramaSize();
  return {calibration_.omni.image_width, calibration_.omni.image_height};
}

cv::Size Unwrapper::panoramaSize() const {
  return {calibration_.panorama.width, calibration_.panorama.height};
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

void Unwrapper::unwrapRows(const cv::Mat& grey, cv::Mat& panorama, int first, int last) const {
  if (options_.input == InputKind::kPanorama) {
    cv::Mat band = panorama.rowRange(first, last);  // a view: convertTo writes in place
    grey.rowRange(first, last).convertTo(band, CV_32F);
    return;
  }
  // Bilinear lookup through the precomputed table.
  const int W = panorama.cols, stride = grey.cols;
  const uint8_t* src = grey.ptr<uint8_t>(0);
  for (int v = first; v < last; ++v) {
    float* dst = panorama.ptr<float>(v);
    const std::size_t row = static_cast<std::size_t>(v) * W;
    for (int u = 0; u < W; ++u) {
      const uint8_t* p = src + offset_[row + u];
      const uint8_t* q = p + stride;
      const cv::Vec4f& w = weight_[row + u];
      dst[u] = w[0] * p[0] + w[1] * p[1] + w[2] * q[0] + w[3] * q[1];
    }
  }
}

}  // namespace omnipose
