#pragma once
/// Formatting of collected start-up problems (private to the libraries): the one place that
/// turns a problem list into text, bounds it and makes every echoed input printable.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <sstream>
#include <stdexcept>
#include <type_traits>
#include <string>
#include <string_view>
#include <vector>

namespace omnipose::detail {

/// At most this many problems are listed; the rest are counted ("and N more").
inline constexpr std::size_t kMaxListedProblems = 20;
/// At most this many characters of an input are echoed in a message.
inline constexpr std::size_t kMaxEchoedChars = 60;

/// `text` with every control character written as an escape (\0, \t, \n, \r, \x01 ...,
/// \x7f), so that no byte of an input can cut or break a message line.
inline std::string escapeControl(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char ch : text) {
    const auto c = static_cast<unsigned char>(ch);
    if (c >= 0x20 && c != 0x7f) {
      out += ch;
      continue;
    }
    switch (c) {
      case 0: out += "\\0"; break;
      case '\t': out += "\\t"; break;
      case '\n': out += "\\n"; break;
      case '\r': out += "\\r"; break;
      default: {
        static constexpr char kHex[] = "0123456789abcdef";
        out += "\\x";
        out += kHex[c >> 4];
        out += kHex[c & 0xf];
      }
    }
  }
  return out;
}

/// An input as a message echoes it: control characters escaped, and when longer than
/// kMaxEchoedChars bytes its first kMaxEchoedChars followed by "... (N bytes)".
inline std::string shown(std::string_view text) {
  if (text.size() <= kMaxEchoedChars) return escapeControl(text);
  return escapeControl(text.substr(0, kMaxEchoedChars)) + "... (" + std::to_string(text.size()) +
         " bytes)";
}

/// The problems, one per line, each indented: what a start-up error's what() lists. At most
/// kMaxListedProblems of them, then "and N more"; control characters escaped.
inline std::string joinProblems(const std::vector<std::string>& problems) {
  std::string out;
  const std::size_t listed = std::min(problems.size(), kMaxListedProblems);
  for (std::size_t i = 0; i < listed; ++i) out += (i == 0 ? "" : "\n  ") + escapeControl(problems[i]);
  if (problems.size() > listed)
    out += "\n  and " + std::to_string(problems.size() - listed) + " more";
  return out;
}

/// Throws std::invalid_argument "<heading>: <problem>" for one problem, or the heading
/// followed by every problem on a line of its own; returns when `problems` is empty.
inline void throwIfProblems(std::string_view heading, const std::vector<std::string>& problems) {
  if (problems.empty()) return;
  std::string what(heading);
  what += problems.size() == 1 ? ": " + escapeControl(problems.front()) : ":\n  " + joinProblems(problems);
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
