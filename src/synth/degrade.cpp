#include <cmath>
#include <opencv2/imgproc.hpp>

#include "omnipose/synth/degrade.hpp"
#include "synth/seeding.hpp"

namespace omnipose::synth {
namespace {

/// Stream of the auto-exposure step signs (detail::itemSeed), apart from a frame's gain,
/// offset and noise draws (stream 0).
constexpr std::uint64_t kExposureStepStream = 1;

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
  if (!(exposure_step >= 0 && exposure_step <= 1)) p.push_back("exposure_step: must be in [0, 1]");
  if (exposure_step_every < 0) p.push_back("exposure_step_every: must be >= 0 (0 = no steps)");
  if (exposure_step_levels < 1 || exposure_step_levels > 16)
    p.push_back("exposure_step_levels: must be in [1, 16]");
  return p;
}

double exposureStepGain(const DegradeOptions& options, std::uint64_t frame) {
  if (const auto problems = options.validate(); !problems.empty()) {
    throw std::invalid_argument("exposureStepGain: " + problems.front());
  }
  if (options.exposure_step == 0.0 || options.exposure_step_every == 0) return 1.0;
  const auto every = static_cast<std::uint64_t>(options.exposure_step_every);
  int level = 0;
  for (std::uint64_t k = every; k <= frame; k += every) {
    cv::RNG rng(detail::itemSeed(options.seed, k, kExposureStepStream));
    const int sign = (rng.next() & 1u) != 0 ? 1 : -1;
    level += std::abs(level + sign) > options.exposure_step_levels ? -sign : sign;
  }
  return std::pow(1.0 + options.exposure_step, level);
}

cv::Mat degrade(const cv::Mat& image, const DegradeOptions& options, std::uint64_t frame) {
  if (const auto problems = options.validate(); !problems.empty()) {
    throw std::invalid_argument("degrade: " + problems.front());
  }
  if (image.empty() || image.type() != CV_32FC1) {
    throw std::invalid_argument("degrade: image must be a non-empty CV_32FC1");
  }
  cv::RNG rng(detail::itemSeed(options.seed, frame));
  // Optics, then exposure I' = g I + o, then sensor noise, then 8-bit rounding and clamping.
  cv::Mat f = options.blur_sigma > 0 ? blur(image, options.blur_sigma, options.periodic_columns)
                                     : image.clone();
  // Without steps A_k = 1 and the product is the jitter's gain exactly.
  const double gain =
      exposureStepGain(options, frame) * (1.0 + rng.gaussian(options.exposure_gain_std));
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
