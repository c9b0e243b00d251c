#pragma once
/// \file wall_clock.hpp
/// The daemon's two clocks: CLOCK_REALTIME microseconds for message timestamps (capture
/// time, publication time) and the steady clock for intervals and deadlines.

#include <chrono>
#include <cstdint>
#include <ctime>

namespace omnipose::daemon {

/// Wall clock (CLOCK_REALTIME), microseconds since the Unix epoch. Allocation-free.
inline std::int64_t wallClockMicros() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000;
}

using SteadyClock = std::chrono::steady_clock;

}  // namespace omnipose::daemon
