#pragma once
// Keys cubic convolution with a = -0.75 (OpenCV's INTER_CUBIC), the image sampler of the
// resamplings whose result is registered by phase correlation: PanoramaWarp's de-rotation, and
// WindowRegistration's per-window de-rotation and de-scaling with Options::cubic_sampling.
// Phase correlation reads any non-linear phase of the sampler as motion: of the cubic kernels
// this one has the most linear phase. Bilinear and a = -0.5 leave shift biases of about
// 0.03 px that depend on the fractional part of the sample position
// (docs/results/experiments/resample_bias.cpp); under a per-window scale that fraction sweeps
// across the window and the bias becomes a spurious shift wherever the texture is uneven
// (docs/results/ANALYSIS.md, "The de-scaling's sampler").

#include "runtime/simd.hpp"

namespace omnipose::image {

/// Weights of the taps at -1, 0, 1, 2 (w[0..3]) for fractional offsets t in [0, 1), four
/// offsets at a time (lane-wise). The four weights of a lane sum to 1.
inline void keysCubicWeights(runtime::simd::F4 t, runtime::simd::F4 w[4]) {
  namespace simd = runtime::simd;
  constexpr float a = -0.75f;
  const simd::F4 one = simd::broadcast(1.0f);
  const auto near = [&](simd::F4 x) {  // |x| <= 1
    return ((simd::broadcast(a + 2) * x - simd::broadcast(a + 3)) * x * x) + one;
  };
  const auto far = [&](simd::F4 x) {  // 1 < |x| < 2
    return ((simd::broadcast(a) * x - simd::broadcast(5 * a)) * x + simd::broadcast(8 * a)) * x -
           simd::broadcast(4 * a);
  };
  w[0] = far(one + t);
  w[1] = near(t);
  w[2] = near(one - t);
  w[3] = far(simd::broadcast(2.0f) - t);
}

}  // namespace omnipose::image
