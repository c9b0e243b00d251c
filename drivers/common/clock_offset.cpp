#include "common/clock_offset.hpp"

namespace omnipose::drivers {

ClockOffset offsetFromSamples(std::span<const ClockSample> samples) {
  ClockOffset best;
  std::int64_t best_span = 0;
  for (const ClockSample& s : samples) {
    const std::int64_t span = s.after_ns - s.before_ns;
    if (span < 0) continue;  // the capture clock went backwards: a broken read
    if (best.valid && span >= best_span) continue;
    // Midpoint of the bracket, written so that it cannot overflow.
    const std::int64_t mid = s.before_ns + span / 2;
    best.offset_ns = s.wall_ns - mid;
    best.uncertainty_ns = (span + 1) / 2;
    best.valid = true;
    best_span = span;
  }
  return best;
}

std::int64_t toWallMicroseconds(std::int64_t capture_ns, const ClockOffset& offset) {
  const std::int64_t wall_ns = capture_ns + offset.offset_ns;
  // floor((wall_ns + 500) / 1000) for either sign.
  const std::int64_t shifted = wall_ns + 500;
  std::int64_t q = shifted / 1000;
  if (shifted % 1000 != 0 && shifted < 0) --q;
  return q;
}

}  // namespace omnipose::drivers
