#pragma once
/// \file wall_clock.hpp
/// The wall clock frames and messages are stamped with: CLOCK_REALTIME, microseconds since
/// the Unix epoch. Allocation-free.

#include <cstdint>
#include <ctime>

namespace omnipose::drivers {

inline std::int64_t wallClockMicros() {
  timespec ts{};
  clock_gettime(CLOCK_REALTIME, &ts);
  return static_cast<std::int64_t>(ts.tv_sec) * 1000000 + ts.tv_nsec / 1000;
}

}  // namespace omnipose::drivers
