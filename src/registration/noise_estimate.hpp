#pragma once
/// \file noise_estimate.hpp
/// The panorama's noise level, measured on every frame (private to the registration).
///
/// Donoho's estimator: the standard deviation of additive white noise is the median of the
/// absolute diagonal Haar details d = (x00 - x01 - x10 + x11) / 2 of the image's 2 x 2
/// blocks over 0.6745 (the median of |N(0, 1)|). A 2 x 2 block of smooth content has d
/// close to 0 whatever its brightness and gradient, so most blocks of a natural image
/// measure the noise alone and the median ignores the edges and texture of the others.
/// Noise that the unwrap's interpolation has low-passed is under-estimated by about the
/// factor by which it attenuates the highest frequencies: what is measured is the noise
/// where it matters most to phase correlation, at the frequencies whose phases it corrupts.
/// Content detailed down to the pixel nearly everywhere (grass, gravel) is read as noise:
/// there the measure is too high (3.6 grey levels on a park photo whose panorama noise is
/// 1.9; docs/results/ANALYSIS.md).

#include <vector>

#include <opencv2/core.hpp>

namespace omnipose::registration {

class NoiseEstimator {
 public:
  /// Blocks of the rows [top, top + rows) of a `width`-column panorama (the rows the
  /// windows cover). `usable` (optional, CV_32FC1 of the panorama's size, 1 = usable): only
  /// blocks whose four pixels are all usable are measured. Allocates the scratch buffer.
  NoiseEstimator(int width, int top, int rows, const cv::Mat& usable = cv::Mat());

  /// Noise standard deviation of `panorama` (CV_32FC1, the size given; grey levels), or
  /// NaN when fewer than kMinBlocks blocks are usable or finite. Allocation-free.
  double sigma(const cv::Mat& panorama);

  /// Blocks measured per frame (after the mask).
  int blocks() const { return static_cast<int>(block_offsets_.size()); }

  static constexpr int kMinBlocks = 64;

 private:
  int width_;
  /// Offset (row * width + column) of the top-left pixel of every usable block.
  std::vector<int> block_offsets_;
  std::vector<float> details_;  ///< scratch: |d| per block
};

}  // namespace omnipose::registration
