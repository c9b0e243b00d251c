#pragma once
/// Formatting of collected start-up problems (private to the calibration stage).

#include <string>
#include <vector>

namespace omnipose::detail {

/// The problems, one per line, each indented: what a start-up error's what() lists.
inline std::string joinProblems(const std::vector<std::string>& problems) {
  std::string out;
  for (const auto& p : problems) out += (out.empty() ? "" : "\n  ") + p;
  return out;
}

}  // namespace omnipose::detail
