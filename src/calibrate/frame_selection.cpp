#include "omnipose/calibrate/frame_selection.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>

namespace omnipose::calibrate {

std::vector<std::size_t> selectEvenly(std::size_t count, std::size_t max_frames) {
  std::vector<std::size_t> out;
  const std::size_t n = std::min(count, max_frames);
  if (n == 0) return out;
  out.reserve(n);
  if (n == 1) {
    out.push_back(0);
    return out;
  }
  const double step = static_cast<double>(count - 1) / static_cast<double>(n - 1);
  for (std::size_t j = 0; j < n; ++j)
    out.push_back(j + 1 == n ? count - 1 : static_cast<std::size_t>(std::llround(j * step)));
  return out;
}

std::size_t centredRunStart(std::size_t count, std::size_t max_frames) {
  return count > max_frames ? (count - max_frames) / 2 : 0;
}

std::string selectionMessage(std::size_t count, std::size_t selected) {
  if (selected >= count)
    return count == 1 ? std::string("using the 1 frame") : "using all " + std::to_string(count) + " frames";
  char buf[160];
  const double step =
      selected > 1 ? static_cast<double>(count - 1) / static_cast<double>(selected - 1) : 0.0;
  if (selected > 1)
    std::snprintf(buf, sizeof buf, "using %zu of %zu frames, every %.1fth (first and last included)",
                  selected, count, step);
  else
    std::snprintf(buf, sizeof buf, "using %zu of %zu frames (the first)", selected, count);
  return buf;
}

}  // namespace omnipose::calibrate
