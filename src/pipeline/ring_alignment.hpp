#pragma once
/// \file ring_alignment.hpp
/// Whole-ring yaw search (private to the core library): the circular shift along u that
/// best aligns a panorama with an earlier one, for a frame whose motion since that panorama
/// is unknown (after a gap). Phase correlation of the two whole panoramas: u wraps around
/// the ring, v is tapered (Hann), so a yaw of any size is found; a tilt of a few degrees or
/// a small translation lowers the peak but leaves it at the yaw's shift.
///
/// Sign: content at column u of the current panorama appears at column u + du of the
/// earlier one (the convention of WindowMotion). Realtime: the constructor allocates
/// everything (plans and buffers); align() allocates nothing.

#include <opencv2/core.hpp>
#include <vector>

#include "runtime/fft_plan.hpp"

namespace omnipose::pipeline {

class RingAlignment {
 public:
  /// For panoramas of `panorama` pixels (CV_32FC1, at least 4 x 4).
  explicit RingAlignment(cv::Size panorama);

  struct Shift {
    double du_px = 0.0;  ///< in (-W/2, W/2], sub-pixel
    double dv_px = 0.0;  ///< the peak's row shift, whole pixels
    double peak = 0.0;   ///< correlation peak height in [0, 1]: 1 = identical up to the
                         ///< shift, about 0.01 for unrelated panoramas of this size
  };
  /// The shift from `current` to `earlier` (both CV_32FC1 of the constructor's size).
  Shift align(const cv::Mat& earlier, const cv::Mat& current);

 private:
  /// Tapered, mean-free copy of `panorama` into input_, transformed and whitened into `out`.
  void whitenedSpectrum(const cv::Mat& panorama, runtime::Complex* out);

  int width_, height_, bins_;
  std::vector<float> taper_;  ///< Hann along v
  runtime::FftwArray<float> input_, surface_;
  runtime::FftwArray<runtime::Complex> spectrum_, earlier_, cross_;
  runtime::FftPlan forward_, inverse_;
};

}  // namespace omnipose::pipeline
