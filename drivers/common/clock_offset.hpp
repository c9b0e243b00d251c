#pragma once
/// \file clock_offset.hpp
/// Capture clocks to wall clock. Drivers stamp frames on a clock that never jumps
/// (V4L2: CLOCK_MONOTONIC, libcamera's SensorTimestamp: CLOCK_BOOTTIME); FrameInfo wants
/// the wall clock (CLOCK_REALTIME) in microseconds. The offset between the two is
/// measured, not assumed:
///
///   one sample   = capture clock (before), wall clock, capture clock (after)
///   offset       = wall - (before + after) / 2        of the sample with the smallest
///                                                       after - before (least preempted)
///   uncertainty  = (after - before) / 2               of that sample
///   wall_us      = round((capture_ns + offset) / 1000)
///
/// Example: samples (1000, 5001100, 1200) and (2000, 5002100, 2200): both span 200 ns,
/// the first wins, offset = 5001100 - 1100 = 5000000 ns; a frame stamped at capture
/// 7,000,400 ns is at wall 12,000,400 ns = 12000 us.
///
/// Everything here is allocation-free, so a driver may re-measure from its per-frame
/// path (to follow an NTP step of the wall clock).

#include <array>
#include <cstdint>
#include <ctime>
#include <span>
#include <sys/time.h>

namespace omnipose::drivers {

/// One bracketed reading, nanoseconds.
struct ClockSample {
  std::int64_t before_ns = 0;  ///< capture clock, read first
  std::int64_t wall_ns = 0;    ///< CLOCK_REALTIME, read second
  std::int64_t after_ns = 0;   ///< capture clock, read third
};

/// wall = capture + offset_ns.
struct ClockOffset {
  std::int64_t offset_ns = 0;       ///< wall minus capture clock, nanoseconds
  std::int64_t uncertainty_ns = 0;  ///< half the bracket of the chosen sample, nanoseconds
  bool valid = false;               ///< false: no usable sample (clock reads failed)
};

/// The most samples measureClockOffset() takes.
inline constexpr int kMaxClockSamples = 16;

/// Offset from samples: the one with the smallest (after - before) wins. Samples with
/// after < before (a broken clock read) are ignored; none left gives valid = false.
ClockOffset offsetFromSamples(std::span<const ClockSample> samples);

/// Takes `samples` (clamped to [1, kMaxClockSamples]) bracketed readings with
/// `read(clockid_t) -> std::int64_t` nanoseconds (negative: the read failed) and returns
/// offsetFromSamples() of them. No allocation.
template <typename ReadClock>
ClockOffset measureClockOffset(ReadClock&& read, clockid_t capture_clock, int samples) {
  std::array<ClockSample, kMaxClockSamples> buffer{};
  if (samples < 1) samples = 1;
  if (samples > kMaxClockSamples) samples = kMaxClockSamples;
  int n = 0;
  for (int i = 0; i < samples; ++i) {
    ClockSample s;
    s.before_ns = read(capture_clock);
    s.wall_ns = read(CLOCK_REALTIME);
    s.after_ns = read(capture_clock);
    if (s.before_ns < 0 || s.wall_ns < 0 || s.after_ns < 0) continue;
    buffer[static_cast<std::size_t>(n++)] = s;
  }
  return offsetFromSamples(std::span<const ClockSample>(buffer.data(), static_cast<std::size_t>(n)));
}

/// Wall-clock microseconds of a capture-clock time in nanoseconds, rounded to the
/// nearest microsecond (halves away from minus infinity).
std::int64_t toWallMicroseconds(std::int64_t capture_ns, const ClockOffset& offset);

/// Nanoseconds of a timespec / timeval (a V4L2 buffer's timestamp is a timeval).
constexpr std::int64_t toNanoseconds(const timespec& t) {
  return static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000 + t.tv_nsec;
}
constexpr std::int64_t toNanoseconds(const timeval& t) {
  return static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000 +
         static_cast<std::int64_t>(t.tv_usec) * 1'000;
}

/// FrameInfo::capture_time_us of a frame stamped `capture_ns` on the capture clock (0 or
/// less: not stamped on it): its wall-clock time when the offset is valid, else the wall
/// time now, `read_wall_ns()` (nanoseconds, CLOCK_REALTIME; called only then), rounded to
/// the nearest microsecond.
template <typename ReadWallNs>
std::int64_t captureTimeUs(std::int64_t capture_ns, const ClockOffset& offset,
                           ReadWallNs&& read_wall_ns) {
  if (capture_ns > 0 && offset.valid) return toWallMicroseconds(capture_ns, offset);
  return (read_wall_ns() + 500) / 1000;
}

}  // namespace omnipose::drivers
