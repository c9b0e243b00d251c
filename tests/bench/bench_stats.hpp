#pragma once
// Statistics shared by the Google Benchmark programs.

#include <algorithm>
#include <vector>

namespace omnipose::bench {

/// The best (smallest) repetition: ComputeStatistics("min", minOf). On a shared machine the
/// minimum is the least disturbed run.
inline double minOf(const std::vector<double>& v) { return *std::min_element(v.begin(), v.end()); }

}  // namespace omnipose::bench
