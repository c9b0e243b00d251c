#pragma once
/// \file gyro_buffer.hpp
/// The recent samples of a live gyro stream, as Odometry keeps them between frames (private
/// to the core library).
///
/// Samples arrive one by one, and some are bad: not finite, faster than any gyro measures
/// (kMaxGyroRate), stamped at or before the last one (given twice, out of order). Those are
/// refused and counted; the buffer keeps only samples in strictly increasing time, so that
/// integrateGyro() can read them as they are. A stamp more than kClockJumpS before the last one
/// is not a late sample but the IMU's clock starting over (a restarted driver, a reset board):
/// the buffer then starts over from it, and counts the jump.
///
/// Realtime: the constructor allocates the whole capacity; nothing else allocates or throws.
/// When full, the oldest half is dropped.

#include <array>
#include <cstddef>
#include <span>
#include <vector>

#include "omnipose/gyro.hpp"

namespace omnipose::imu {

/// What became of a sample pushed.
enum class GyroIntake {
  kAccepted,
  kNotFinite,     ///< a NaN or infinite time or rate
  kTooFast,       ///< a rate beyond kMaxGyroRate about some axis
  kOutOfOrder,    ///< stamped at or before the last sample (within kClockJumpS of it)
  kClockRestart,  ///< accepted, after emptying the buffer: the clock jumped back
};

class GyroBuffer {
 public:
  /// A stamp this much before the last sample's, seconds, is the IMU's clock starting over.
  static constexpr double kClockJumpS = 1.0;

  /// `capacity` samples (at least 16), allocated here.
  explicit GyroBuffer(std::size_t capacity);

  GyroIntake push(const GyroSample& sample);
  /// The samples kept, oldest first, t strictly increasing. Valid until the next push().
  std::span<const GyroSample> samples() const { return samples_; }
  /// The median of the last (up to 15) intervals between samples, seconds; 0 with fewer
  /// than two samples. A gap is longer than kGyroGapIntervals of these.
  double typicalInterval() const;
  void clear() { samples_.clear(); }

 private:
  std::vector<GyroSample> samples_;
  std::size_t capacity_;
};

}  // namespace omnipose::imu
