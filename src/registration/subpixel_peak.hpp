#pragma once
/// \file subpixel_peak.hpp
/// Integer peak search on a periodic 2-D surface within a region around zero shift, and
/// sub-sample refinement by a 3-point fit per axis.

namespace omnipose::registration {

/// A periodic rows x cols surface, row-major; index i means shift i (i < n/2) or i - n.
struct SurfaceView {
  const float* data;
  int rows;
  int cols;

  float at(int r, int c) const;  ///< value at any (r, c), wrapped into the surface
};

/// Shifts searched: d0 in [lo0, hi0], d1 in [lo1, hi1] (surface samples, may be negative).
struct SearchRegion {
  int lo0, hi0, lo1, hi1;

  /// |d| <= reach per axis (surface samples); a reach of n/2 or more covers the whole axis.
  static SearchRegion around(const SurfaceView& surface, double reach0, double reach1);
  int count0() const { return hi0 - lo0 + 1; }
  int count1() const { return hi1 - lo1 + 1; }
};

struct SubpixelPeak {
  double x0 = 0.0;         ///< sub-sample peak position along rows, surface samples (signed)
  double x1 = 0.0;         ///< along columns
  double value = 0.0;      ///< fitted peak value
  /// Curvature of the fitted surface at the peak, -(second derivatives), value units per
  /// surface sample^2 (rows 0, columns 1; 01 from the diagonal neighbours when all of them
  /// are positive, else 0). 0 along an axis without a vertex: a ridge.
  double curvature00 = 0.0;
  double curvature01 = 0.0;
  double curvature11 = 0.0;
  bool on_border = false;  ///< integer maximum on the border of a restricted region
};

/// Vertex of the curve through the samples (-1, m), (0, c), (1, p), c being the largest.
struct Vertex1d {
  double offset = 0.0;  ///< vertex position relative to the centre sample
  double gain = 1.0;    ///< Gaussian: peak / c; parabola: unused (1)
  double add = 0.0;     ///< parabola: peak - c; Gaussian: 0
  double a = 0.0;       ///< the quadratic's t^2 coefficient (< 0 at a vertex; else 0)
  bool gaussian = false;  ///< the log model was used (a is of the logarithm)
};
/// A Gaussian (parabola of the logarithms) when all three samples are positive, which is
/// exact for the Gaussian-weighted phase-correlation peak; else (a non-positive value, as
/// near a weak or negative correlation) a parabola of the values. Offset clamped to [-1, 1].
Vertex1d fitVertex(double m, double c, double p);

/// Largest sample in `region`, refined per axis by fitVertex().
SubpixelPeak findPeak(const SurfaceView& surface, const SearchRegion& region);

}  // namespace omnipose::registration
