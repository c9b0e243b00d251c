#pragma once
/// \file wall_clock.hpp
/// The daemon's two clocks: CLOCK_REALTIME microseconds for message timestamps (capture
/// time, publication time) and the steady clock for intervals and deadlines.

#include <chrono>

#include "common/wall_clock.hpp"

namespace omnipose::daemon {

/// Wall clock (CLOCK_REALTIME), microseconds since the Unix epoch: the drivers' clock.
using drivers::wallClockMicros;

using SteadyClock = std::chrono::steady_clock;

}  // namespace omnipose::daemon
