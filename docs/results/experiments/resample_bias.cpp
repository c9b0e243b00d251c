// Why ifmi's yaw error is larger than its roll/pitch error (docs/results/ANALYSIS.md).
//
// A panorama is shifted along u by s = base + d columns with an exact Fourier shift (no
// interpolation), then registered window by window against the original:
//   1. directly (what the first pass sees): the error of the mean du is the peak bias;
//   2. after "de-rotating" it back by s with an interpolating resampler (what the
//      refinement pass sees): the mean residual du should be 0 for every d.
// Uses only the public WindowRegistration API.
//
// Built with the project (target omnipose-experiment-resample-bias); run from the
// repository root:
//   build/bin/omnipose-experiment-resample-bias PANORAMA.png
//     (an 1100 x 110 panorama, e.g. a rendered frame)

#include <cmath>
#include <cstdio>
#include <numbers>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "omnipose/window_registration.hpp"

namespace {

/// out(u) = img(u - s), periodic in u, by the Fourier shift theorem (row by row).
cv::Mat fourierShift(const cv::Mat& img, double s) {
  cv::Mat out(img.size(), CV_32F);
  const int W = img.cols;
  for (int v = 0; v < img.rows; ++v) {
    cv::Mat row, spec, back;
    img.row(v).convertTo(row, CV_64F);
    cv::dft(row, spec, cv::DFT_COMPLEX_OUTPUT);
    for (int k = 0; k < W; ++k) {
      const int f = k <= W / 2 ? k : k - W;
      const double phase = (W % 2 == 0 && k == W / 2) ? 0.0 : -2 * std::numbers::pi * f * s / W;
      cv::Vec2d& c = spec.at<cv::Vec2d>(0, k);
      c = {c[0] * std::cos(phase) - c[1] * std::sin(phase),
           c[0] * std::sin(phase) + c[1] * std::cos(phase)};
    }
    cv::dft(spec, back, cv::DFT_INVERSE | cv::DFT_SCALE | cv::DFT_REAL_OUTPUT);
    back.convertTo(out.row(v), CV_32F);
  }
  return out;
}

enum class Kernel { kLinear, kKeys05, kOpenCvCubic, kLanczos4 };
const char* name(Kernel k) {
  switch (k) {
    case Kernel::kLinear: return "bilinear";
    case Kernel::kKeys05: return "Keys cubic a=-0.5";
    case Kernel::kOpenCvCubic: return "OpenCV cubic a=-0.75";
    case Kernel::kLanczos4: return "Lanczos-4";
  }
  return "";
}

/// img sampled at u + s (periodic): undoes fourierShift(img, s) up to interpolation.
cv::Mat resampleBack(const cv::Mat& img, double s, Kernel kernel) {
  constexpr int kPad = 32;
  cv::Mat padded, out(img.size(), CV_32F);
  cv::copyMakeBorder(img, padded, 0, 0, kPad, kPad, cv::BORDER_WRAP);
  if (kernel == Kernel::kKeys05) {
    for (int v = 0; v < img.rows; ++v) {
      const float* r = padded.ptr<float>(v);
      for (int u = 0; u < img.cols; ++u) {
        const double x = u + s + kPad;
        const int x0 = static_cast<int>(std::floor(x));
        const float t = static_cast<float>(x - x0), t2 = t * t, t3 = t2 * t;
        const float w[4] = {-0.5f * t3 + t2 - 0.5f * t, 1.5f * t3 - 2.5f * t2 + 1.0f,
                            -1.5f * t3 + 2.0f * t2 + 0.5f * t, 0.5f * t3 - 0.5f * t2};
        out.at<float>(v, u) = w[0] * r[x0 - 1] + w[1] * r[x0] + w[2] * r[x0 + 1] + w[3] * r[x0 + 2];
      }
    }
    return out;
  }
  cv::Mat mx(img.size(), CV_32F), my(img.size(), CV_32F);
  for (int v = 0; v < img.rows; ++v)
    for (int u = 0; u < img.cols; ++u) {
      mx.at<float>(v, u) = static_cast<float>(u + s + kPad);
      my.at<float>(v, u) = static_cast<float>(v);
    }
  const int flag = kernel == Kernel::kLinear ? cv::INTER_LINEAR
                   : kernel == Kernel::kOpenCvCubic ? cv::INTER_CUBIC
                                                    : cv::INTER_LANCZOS4;
  cv::remap(padded, out, mx, my, flag, cv::BORDER_REPLICATE);
  return out;
}

double meanDu(omnipose::WindowRegistration& reg, const cv::Mat& reference, const cv::Mat& current) {
  std::vector<omnipose::WindowMotion> w(reg.windowCount());
  reg.setReference(reference);
  reg.measure(current, w, false);
  double sum = 0;
  int n = 0;
  for (const auto& m : w)
    if (m.valid) sum += m.du, ++n;
  return n > 0 ? sum / n : NAN;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 2) {
    std::fprintf(stderr, "usage: resample_bias PANORAMA.png\n");
    return 2;
  }
  cv::Mat pano;
  cv::imread(argv[1], cv::IMREAD_GRAYSCALE).convertTo(pano, CV_32F);
  omnipose::WindowRegistration::Options options;
  options.window = std::min(options.window, pano.rows);
  omnipose::WindowRegistration reg(pano.size(), options);

  std::printf("1. exact shift, registered directly: error of the mean du [px]\n   d:");
  const double ds[] = {-0.375, -0.25, -0.125, 0.0, 0.125, 0.25, 0.375, 0.5};
  for (double d : ds) std::printf(" %+7.3f", d);
  for (double base : {0.0, 7.0}) {
    std::printf("\n   s = %.0f + d:", base);
    for (double d : ds) {
      const double s = base + d;
      // Content at u of the current appears at u + s in the reference: current = shift by -s.
      std::printf(" %+7.4f", meanDu(reg, pano, fourierShift(pano, -s)) - s);
    }
  }
  std::printf("\n2. exact shift by 7 + d, resampled back by 7 + d: residual mean du [px]\n");
  for (Kernel k : {Kernel::kLinear, Kernel::kKeys05, Kernel::kOpenCvCubic, Kernel::kLanczos4}) {
    std::printf("   %-22s", name(k));
    for (double d : ds) {
      const double s = 7.0 + d;
      std::printf(" %+7.4f", meanDu(reg, pano, resampleBack(fourierShift(pano, -s), -s, k)));
    }
    std::printf("\n");
  }
  return 0;
}
