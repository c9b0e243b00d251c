#pragma once
/// Formatting of collected start-up problems (private to the core library's stages).

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <type_traits>
#include <string>
#include <string_view>
#include <vector>

namespace omnipose::detail {

/// The problems, one per line, each indented: what a start-up error's what() lists.
inline std::string joinProblems(const std::vector<std::string>& problems) {
  std::string out;
  for (const auto& p : problems) out += (out.empty() ? "" : "\n  ") + p;
  return out;
}

/// Throws std::invalid_argument "<heading>: <problem>" for one problem, or the heading
/// followed by every problem on a line of its own; returns when `problems` is empty.
inline void throwIfProblems(std::string_view heading, const std::vector<std::string>& problems) {
  if (problems.empty()) return;
  std::string what(heading);
  what += problems.size() == 1 ? ": " + problems.front() : ":\n  " + joinProblems(problems);
  throw std::invalid_argument(what);
}

/// Appends a problem unless lo <= value <= hi (lo < value with `open_below`), naming `field`:
/// "<field>: must be a finite number, not nan" for NaN or an infinity, else
/// "<field>: <value> is outside [lo, hi]<unit>". The one wording of every range problem.
template <typename T>
void checkRange(std::vector<std::string>& problems, std::string_view field, T value, T lo, T hi,
                std::string_view unit = {}, bool open_below = false) {
  auto text = [](T v) {
    std::ostringstream o;
    o << v;
    return o.str();
  };
  if constexpr (std::is_floating_point_v<T>) {
    if (!std::isfinite(value)) {
      problems.push_back(std::string(field) + ": must be a finite number, not " + text(value));
      return;
    }
  }
  if (open_below ? value > lo && value <= hi : value >= lo && value <= hi) return;
  problems.push_back(std::string(field) + ": " + text(value) + " is outside " +
                     (open_below ? "(" : "[") + text(lo) + ", " + text(hi) + "]" +
                     std::string(unit));
}

}  // namespace omnipose::detail
