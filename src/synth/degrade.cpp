#include <cmath>
#include <opencv2/imgproc.hpp>

#include "omnipose/synth/synth.hpp"

namespace omnipose::synth {
namespace {

/// SplitMix64 finaliser: decorrelates nearby seeds.
std::uint64_t splitMix(std::uint64_t x) {
  x += 0x9e3779b97f4a7c15ULL;
  x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
  x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
  return x ^ (x >> 31);
}

/// Gaussian blur; with periodic columns the image wraps around horizontally.
cv::Mat blur(const cv::Mat& image, double sigma, bool periodic_columns) {
  cv::Mat out;
  if (!periodic_columns) {
    cv::GaussianBlur(image, out, cv::Size(), sigma, sigma, cv::BORDER_REFLECT101);
    return out;
  }
  const int pad = std::min(image.cols, static_cast<int>(std::ceil(4.0 * sigma)) + 1);
  cv::Mat padded;
  cv::copyMakeBorder(image, padded, 0, 0, pad, pad, cv::BORDER_WRAP);
  cv::GaussianBlur(padded, padded, cv::Size(), sigma, sigma, cv::BORDER_REFLECT101);
  padded(cv::Rect(pad, 0, image.cols, image.rows)).copyTo(out);
  return out;
}

}  // namespace

std::vector<std::string> DegradeOptions::validate() const {
  std::vector<std::string> p;
  if (!(noise_sigma >= 0)) p.push_back("noise_sigma: must be >= 0");
  if (!(blur_sigma >= 0)) p.push_back("blur_sigma: must be >= 0");
  if (!(exposure_gain_std >= 0)) p.push_back("exposure_gain_std: must be >= 0");
  if (!(exposure_offset_std >= 0)) p.push_back("exposure_offset_std: must be >= 0");
  return p;
}

cv::Mat degrade(const cv::Mat& image, const DegradeOptions& options, std::uint64_t frame) {
  if (const auto problems = options.validate(); !problems.empty()) {
    throw std::invalid_argument("degrade: " + problems.front());
  }
  if (image.empty() || image.type() != CV_32FC1) {
    throw std::invalid_argument("degrade: image must be a non-empty CV_32FC1");
  }
  cv::RNG rng(splitMix(options.seed ^ splitMix(frame)));
  // Optics, then exposure I' = g I + o, then sensor noise, then 8-bit rounding and clamping.
  cv::Mat f = options.blur_sigma > 0 ? blur(image, options.blur_sigma, options.periodic_columns)
                                     : image.clone();
  const double gain = 1.0 + rng.gaussian(options.exposure_gain_std);
  const double offset = rng.gaussian(options.exposure_offset_std);
  f.convertTo(f, CV_32FC1, gain, offset);
  if (options.noise_sigma > 0) {
    cv::Mat noise(f.size(), CV_32FC1);
    rng.fill(noise, cv::RNG::NORMAL, 0.0, options.noise_sigma);
    f += noise;
  }
  cv::Mat out;
  f.convertTo(out, CV_8UC1);
  return out;
}

}  // namespace omnipose::synth
