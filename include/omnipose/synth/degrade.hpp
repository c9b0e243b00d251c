#pragma once
/// \file degrade.hpp
/// Sensor degradations of a rendered image: blur, exposure, auto-exposure steps, noise.

#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace omnipose::synth {

/// Sensor effects applied to a rendered float image, in this order: Gaussian blur (optics),
/// exposure (gain, offset), Gaussian noise, rounding to 8 bit. JPEG compression is applied
/// when the frame is written (DatasetWriter). All random draws are seeded by (seed, frame),
/// so a frame's degradation does not depend on which other frames were rendered.
///
/// Exposure: I' = g_k I + o with g_k = A_k * (1 + N(0, exposure_gain_std)), A_k the
/// auto-exposure gain of frame k (exposureStepGain) and o ~ N(0, exposure_offset_std).
///
/// Auto-exposure steps: the gain a controller sets steps now and then by a whole factor:
///   A_k = (1 + exposure_step)^n_k,
/// n_0 = 0; n_k = n_{k-1} except at the step frames k = m * exposure_step_every (m >= 1),
/// where a sign s_k = +1 or -1 (probability 1/2, drawn from a generator seeded by (seed, k)
/// alone, apart from the frame's other draws) gives n_k = n_{k-1} + s_k, or n_{k-1} - s_k
/// when |n_{k-1} + s_k| would exceed exposure_step_levels (the controller's range). So
/// exposure_step = 0.25 makes each step x1.25 or /1.25, and A_k depends on (seed, k) only.
struct DegradeOptions {
  double noise_sigma = 0.0;          ///< sensor noise std, grey levels
  double blur_sigma = 0.0;           ///< Gaussian blur std, pixels (0 = off)
  double exposure_gain_std = 0.0;    ///< per-frame gain 1 + N(0, std) (e.g. 0.05)
  double exposure_offset_std = 0.0;  ///< per-frame offset N(0, std), grey levels
  std::uint64_t seed = 0;
  bool periodic_columns = false;     ///< blur wraps around columns (panorama output)
  double exposure_step = 0.0;        ///< auto-exposure step, relative, [0, 1] (0 = none)
  int exposure_step_every = 0;       ///< frames between steps, >= 0 (0 = none)
  int exposure_step_levels = 2;      ///< most steps away from the start gain, [1, 16]

  /// One message per bad field (empty = valid): every std >= 0, the steps' ranges above.
  std::vector<std::string> validate() const;
};

/// A_k, the auto-exposure gain of frame `frame` (see DegradeOptions): 1 without steps.
/// Costs frame / exposure_step_every draws. Throws std::invalid_argument on invalid options.
double exposureStepGain(const DegradeOptions& options, std::uint64_t frame);

/// Applies the degradations to a CV_32FC1 image (grey 0..255) for frame number `frame`;
/// returns CV_8UC1 (values rounded and clamped to 0..255). Deterministic for the same
/// options and frame. Throws std::invalid_argument on invalid options or a non-float image.
cv::Mat degrade(const cv::Mat& image, const DegradeOptions& options, std::uint64_t frame);

}  // namespace omnipose::synth
