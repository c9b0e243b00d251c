#include "pipeline/capture_time_offset.hpp"

#include <algorithm>
#include <cmath>

namespace omnipose::pipeline {

void CaptureTimeOffset::Sums::add(double x, double y, double weight) {
  n = kForget * n + weight;
  sx = kForget * sx + weight * x;
  sy = kForget * sy + weight * y;
  sxx = kForget * sxx + weight * x * x;
  sxy = kForget * sxy + weight * x * y;
  syy = kForget * syy + weight * y * y;
}

CaptureTimeOffset::Line CaptureTimeOffset::Sums::fit() const {
  Line line;
  if (!(n > 2.0)) return line;
  // Centred sums: the intercept takes the bias the gyro's estimate has not yet removed.
  const double cxx = std::max(0.0, sxx - sx * sx / n), cxy = sxy - sx * sy / n;
  const double cyy = std::max(0.0, syy - sy * sy / n);
  line.slope = cxy / (cxx + kRidge);
  line.intercept = (sy - line.slope * sx) / n;
  const double residual =
      std::max(0.0, cyy - 2.0 * line.slope * cxy + line.slope * line.slope * cxx);
  line.scatter = residual / (n - 2.0);
  line.slope_variance = line.scatter / (cxx + kRidge);
  return line;
}

bool CaptureTimeOffset::update(double beyond_rad, double rate_change, double used_offset_s) {
  if (!std::isfinite(beyond_rad) || !std::isfinite(rate_change) ||
      !std::isfinite(used_offset_s) || !(std::abs(beyond_rad) <= kMaxReadingRad))
    return false;
  // The pair's yaw as it would have been without the correction (first order in the offset).
  const double x = rate_change, y = beyond_rad + used_offset_s * rate_change;
  if (readings_ < kWarmUp) {
    first_[static_cast<std::size_t>(readings_)] = {x, y};
    if (++readings_ == kWarmUp) startFromFirst();
    return true;
  }
  if (!sums_.fit().holds(x, y)) return false;
  sums_.add(x, y, 1.0);
  ++readings_;
  setOffset(sums_.fit());
  return true;
}

void CaptureTimeOffset::startFromFirst() {
  // The first readings fitted, those beyond kMaxSigmas of that fit (a pair the images got
  // wrong would set the offset alone) left out, the rest kept as if read one by one.
  Sums all;
  for (const auto& [x, y] : first_) all.add(x, y, 1.0);
  const Line line = all.fit();
  for (const auto& [x, y] : first_) sums_.add(x, y, line.holds(x, y) ? 1.0 : 0.0);
  setOffset(sums_.fit());
}

void CaptureTimeOffset::setOffset(const Line& line) {
  // Shrunk by its standard error (James-Stein): one within a standard error of 0 is not used.
  offset_ = 0.0;
  if (!std::isfinite(line.slope) || line.slope == 0.0) return;
  const double shrink = std::max(0.0, 1.0 - line.slope_variance / (line.slope * line.slope));
  offset_ = std::clamp(line.slope * shrink, -kMaxOffsetS, kMaxOffsetS);
}

}  // namespace omnipose::pipeline
