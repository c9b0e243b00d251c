#pragma once
/// \file format.hpp
/// printf into a std::string of the length it needs (private to the libraries). The compiler
/// checks the arguments against the format (-Wformat), as for printf itself.

#include <cstdarg>
#include <cstdio>
#include <string>

namespace omnipose::detail {

[[gnu::format(printf, 1, 2)]] inline std::string format(const char* fmt, ...) {
  std::va_list args;
  va_start(args, fmt);
  std::va_list copy;
  va_copy(copy, args);
  const int n = std::vsnprintf(nullptr, 0, fmt, copy);
  va_end(copy);
  std::string out(n > 0 ? static_cast<std::size_t>(n) : 0, '\0');
  if (n > 0) std::vsnprintf(out.data(), out.size() + 1, fmt, args);
  va_end(args);
  return out;
}

/// `v` with `digits` decimals ("%.*f").
inline std::string fixed(double v, int digits) { return format("%.*f", digits, v); }

}  // namespace omnipose::detail
