#include "registration/subpixel_peak.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include "common/periodic.hpp"
#include "runtime/simd.hpp"

namespace omnipose::registration {

namespace simd = runtime::simd;
namespace {

using detail::wrapIndex;

/// Signed range [-reach, reach] clipped to one period [-n/2, n - n/2 - 1].
void clipRange(double reach, int n, int& lo, int& hi) {
  const int half = n / 2;
  if (!(reach < half)) {  // also catches NaN / infinity: whole axis
    lo = -half;
    hi = n - half - 1;
    return;
  }
  const int r = std::max(0, static_cast<int>(std::floor(reach)));
  lo = -r;
  hi = r;
}

}  // namespace

float SurfaceView::at(int r, int c) const {
  return data[static_cast<long>(wrapIndex(r, rows)) * cols + wrapIndex(c, cols)];
}

SearchRegion SearchRegion::around(const SurfaceView& surface, double reach0, double reach1) {
  SearchRegion region{};
  clipRange(reach0, surface.rows, region.lo0, region.hi0);
  clipRange(reach1, surface.cols, region.lo1, region.hi1);
  return region;
}

Vertex1d fitVertex(double m, double c, double p) {
  Vertex1d v;
  if (m > 0.0 && c > 0.0 && p > 0.0) {
    // Gaussian: parabola through the logarithms, y(t) = y0 + b t + a t^2.
    const double lm = std::log(m), lc = std::log(c), lp = std::log(p);
    const double a = 0.5 * (lp + lm) - lc;
    const double b = 0.5 * (lp - lm);
    v.gaussian = true;
    if (a < 0.0) {
      v.offset = std::clamp(-b / (2.0 * a), -1.0, 1.0);
      v.gain = std::exp(b * v.offset + a * v.offset * v.offset);  // exp(y(t*) - y0)
      v.a = a;
    }
    return v;
  }
  // Parabola through the values themselves (a value <= 0: the log model does not apply).
  const double a = 0.5 * (p + m) - c;
  const double b = 0.5 * (p - m);
  if (a < 0.0) {
    v.offset = std::clamp(-b / (2.0 * a), -1.0, 1.0);
    v.add = b * v.offset + a * v.offset * v.offset;
    v.a = a;
  }
  return v;
}

/// Largest value of p[0 .. count). Four independent running maxima over 16 values at a
/// time: one chain of vector maxima would wait on each one's latency. Inlined into each copy
/// of findPeak() (OMNIPOSE_SIMD_CLONES).
[[gnu::always_inline]] inline float segmentMax(const float* p, int count) {
  const simd::F4 lowest = simd::broadcast(-std::numeric_limits<float>::infinity());
  simd::F4 b0 = lowest, b1 = lowest, b2 = lowest, b3 = lowest;
  int j = 0;
  for (; j + 16 <= count; j += 16) {
    b0 = simd::max(b0, simd::load(p + j));
    b1 = simd::max(b1, simd::load(p + j + 4));
    b2 = simd::max(b2, simd::load(p + j + 8));
    b3 = simd::max(b3, simd::load(p + j + 12));
  }
  simd::F4 best4 = simd::max(simd::max(b0, b1), simd::max(b2, b3));
  for (; j + 4 <= count; j += 4) best4 = simd::max(best4, simd::load(p + j));
  float best = simd::maxLane(best4);
  for (; j < count; ++j) best = std::max(best, p[j]);
  return best;
}

OMNIPOSE_SIMD_CLONES
SubpixelPeak findPeak(const SurfaceView& surface, const SearchRegion& region) {
  // Columns d1 in [lo1, hi1] are two contiguous runs: [0, hi1] and [cols + lo1, cols).
  const int cols = surface.cols;
  const bool all_cols = region.count1() >= cols;
  const int run0 = all_cols ? cols : region.hi1 + 1;
  const int run1_start = all_cols ? cols : cols + region.lo1;
  // Integer maximum: best row by vectorised row maxima, then its column.
  float best = -std::numeric_limits<float>::infinity();
  int best0 = 0;
  for (int d0 = region.lo0; d0 <= region.hi0; ++d0) {
    const float* row = surface.data + static_cast<long>(wrapIndex(d0, surface.rows)) * cols;
    const float m = std::max(segmentMax(row, run0), segmentMax(row + run1_start, cols - run1_start));
    if (m > best) {
      best = m;
      best0 = d0;
    }
  }
  const float* row = surface.data + static_cast<long>(wrapIndex(best0, surface.rows)) * cols;
  int best1 = 0;
  for (int j = 0; j < cols; ++j) {
    const bool inside = j < run0 || j >= run1_start;
    if (inside && row[j] == best) {
      best1 = (all_cols ? j >= cols - cols / 2 : j >= run1_start) ? j - cols : j;
      break;
    }
  }
  SubpixelPeak peak;
  const bool restricted0 = region.count0() < surface.rows;
  const bool restricted1 = region.count1() < surface.cols;
  peak.on_border = (restricted0 && (best0 == region.lo0 || best0 == region.hi0)) ||
                   (restricted1 && (best1 == region.lo1 || best1 == region.hi1));
  // Sub-sample vertex per axis, from the neighbours across the wrap-around.
  const double c = best;
  const Vertex1d v0 = fitVertex(surface.at(best0 - 1, best1), c, surface.at(best0 + 1, best1));
  const Vertex1d v1 = fitVertex(surface.at(best0, best1 - 1), c, surface.at(best0, best1 + 1));
  peak.x0 = best0 + v0.offset;
  peak.x1 = best1 + v1.offset;
  peak.value = c * v0.gain * v1.gain + v0.add + v1.add;
  // Curvature: of exp(quadratic) at its vertex, value times the quadratic's (Gaussian);
  // the parabola's own (else). The mixed term from the four diagonal neighbours' logarithms.
  const auto curvature = [&](const Vertex1d& v) {
    return -2.0 * v.a * (v.gaussian ? peak.value : 1.0);
  };
  peak.curvature00 = curvature(v0);
  peak.curvature11 = curvature(v1);
  if (v0.gaussian && v1.gaussian) {
    const double pp = surface.at(best0 + 1, best1 + 1), pm = surface.at(best0 + 1, best1 - 1);
    const double mp = surface.at(best0 - 1, best1 + 1), mm = surface.at(best0 - 1, best1 - 1);
    if (pp > 0.0 && pm > 0.0 && mp > 0.0 && mm > 0.0)
      peak.curvature01 =
          -0.25 * (std::log(pp) - std::log(pm) - std::log(mp) + std::log(mm)) * peak.value;
  }
  return peak;
}

}  // namespace omnipose::registration
