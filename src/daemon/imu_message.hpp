#pragma once
/// \file imu_message.hpp (private to the daemon)
/// The robot's gyro over LCM: an omnipose.imu_t message (lcm_types/imu_t.lcm) as a
/// subscriber receives its bytes, turned into a GyroSample or refused with the reason.

#include <cstdint>
#include <span>

#include "omnipose/error.hpp"
#include "omnipose/gyro.hpp"

namespace omnipose::daemon {

/// The sample of `bytes`, one LCM-encoded omnipose.imu_t: t = utime / 1e6 seconds, the
/// rate gyro[0..2] rad/s (the accelerometer is not read). An Error (kInvalidArgument) names
/// what is wrong: bytes that do not decode as an imu_t (too short, another type's
/// fingerprint), bytes left over after it, a utime that is not positive, or a rate that is
/// not finite or beyond kMaxGyroRate. Never throws; allocates nothing.
Expected<GyroSample> decodeImuMessage(std::span<const std::uint8_t> bytes);

}  // namespace omnipose::daemon
