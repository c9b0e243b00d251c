#include "omnipose/calibrate/mask_proposal.hpp"
#include "omnipose/calibrate/ring_detector.hpp"

#include <algorithm>
#include <cmath>
#include <vector>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "common/format.hpp"

namespace omnipose::calibrate {
namespace {


using omnipose::detail::format;

}  // namespace

MaskProposal proposeMask(std::span<const cv::Mat> frames, const MaskProposalOptions& o) {
  if (frames.size() < 3)
    throw std::runtime_error("--propose-mask needs at least 3 frames of a moving robot, got " +
                             std::to_string(frames.size()));
  const cv::Size size = frames.front().size();
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (frames[k].size() != size || frames[k].depth() != CV_8U)
      throw std::runtime_error("--propose-mask: frame " + std::to_string(k) +
                               " differs in size or depth from the first");
  }
  // Evidence per patch (pool_px square about each pixel), so that weak texture counts:
  //   C2 = mean over frame pairs and the patch of the squared frame-to-frame change,
  //   V  = mean over frames of the patch's variance (texture plus noise).
  // Noise alone gives C2 = 2 s^2 (s: sensor noise); a patch that moves by more than its
  // texture's correlation length gives about 2 V. Still patches stay near 2 s^2.
  const cv::Size pool(o.pool_px, o.pool_px);
  // The frames one at a time: only the previous grey image is kept.
  cv::Mat c2(size, CV_32F, cv::Scalar(0)), variance(size, CV_32F, cv::Scalar(0));
  cv::Mat prev;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const cv::Mat grey = toGreyFloat(frames[k]);
    cv::Mat mean, mean_sq, square;
    cv::boxFilter(grey, mean, CV_32F, pool);
    cv::boxFilter(grey.mul(grey), mean_sq, CV_32F, pool);
    variance += (mean_sq - mean.mul(mean)) / static_cast<double>(frames.size());
    if (k > 0) {
      const cv::Mat diff = grey - prev;
      cv::boxFilter(diff.mul(diff), square, CV_32F, pool);
      c2 += square / static_cast<double>(frames.size() - 1);
    }
    prev = grey;
  }
  // Sensor noise 2 s^2: the 10th percentile of C2 (still, flat parts: lens body, centre).
  std::vector<float> all(c2.begin<float>(), c2.end<float>());
  std::nth_element(all.begin(), all.begin() + all.size() / 10, all.end());
  const double noise2 = std::max(0.25, static_cast<double>(all[all.size() / 10]));
  // Decidable: texture clearly above the noise. Still: change within the noise plus a small
  // fraction of the texture (a fraction of a pixel of motion).
  const cv::Mat signal = variance - 0.5 * noise2;
  const cv::Mat decidable = signal > o.min_texture_snr * 0.5 * noise2;
  const int n_decidable = cv::countNonZero(decidable);
  if (n_decidable < 100)
    throw std::runtime_error("--propose-mask: the frames have almost no texture to tell moving "
                             "from still pixels");
  const cv::Mat is_static =
      (c2 < o.static_noise * noise2 + o.static_fraction * signal) & decidable;
  MaskProposal result;
  result.moving_fraction = 1.0 - cv::countNonZero(is_static) / static_cast<double>(n_decidable);
  if (result.moving_fraction < o.min_moving_fraction)
    throw std::runtime_error(format("--propose-mask: the scene hardly moved between these frames "
                                    "(%.0f %% of the textured patches moved, need %.0f %%): record "
                                    "a short turn of the robot",
                                    100.0 * result.moving_fraction, 100.0 * o.min_moving_fraction));
  // Close the gaps between textured parts of one object, then grow the border.
  cv::Mat masked;
  cv::morphologyEx(is_static, masked, cv::MORPH_CLOSE,
                   cv::getStructuringElement(cv::MORPH_ELLIPSE, pool));
  if (o.grow_px > 0)
    cv::dilate(masked, masked, cv::getStructuringElement(
                                   cv::MORPH_ELLIPSE, {2 * o.grow_px + 1, 2 * o.grow_px + 1}));
  result.mask = cv::Mat(size, CV_8UC1, cv::Scalar(255));
  result.mask.setTo(0, masked);
  result.masked_fraction = cv::countNonZero(masked) / static_cast<double>(size.area());
  result.notes.push_back(std::to_string(frames.size()) + " frames; " +
                        format("%.0f %% of the textured patches moved", 100.0 * result.moving_fraction));
  result.notes.push_back(format("masked %.1f %% of the frame: textured patches that stayed still "
                                "(within the noise, sensor noise %.1f grey levels)",
                                100.0 * result.masked_fraction, std::sqrt(0.5 * noise2)));
  return result;
}

cv::Mat renderMaskPreview(std::span<const cv::Mat> frames, const cv::Mat& mask) {
  cv::Mat mean(frames.front().size(), CV_32F, cv::Scalar(0));
  for (const cv::Mat& f : frames) mean += toGreyFloat(f) / static_cast<double>(frames.size());
  cv::Mat grey8, colour;
  mean.convertTo(grey8, CV_8U);
  cv::cvtColor(grey8, colour, cv::COLOR_GRAY2BGR);
  cv::Mat tinted = colour.clone();
  tinted.setTo(cv::Scalar(0, 0, 255), mask == 0);
  cv::addWeighted(colour, 0.5, tinted, 0.5, 0.0, colour);
  return colour;
}

}  // namespace omnipose::calibrate
