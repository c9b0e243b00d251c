#pragma once
/// \file periodic.hpp
/// Index arithmetic on periodic axes (private to the libraries): the panorama's columns, the
/// ring of windows, a correlation surface.

namespace omnipose::detail {

/// i wrapped into [0, n), for any i (negative ones too); n > 0.
constexpr int wrapIndex(int i, int n) {
  const int r = i % n;
  return r < 0 ? r + n : r;
}

}  // namespace omnipose::detail
