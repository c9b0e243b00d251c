#include "daemon/imu_message.hpp"

#include <cmath>

#include "omnipose/imu_t.hpp"

namespace omnipose::daemon {

Expected<GyroSample> decodeImuMessage(std::span<const std::uint8_t> bytes) {
  imu_t message;
  const auto size = static_cast<int>(std::min<std::size_t>(bytes.size(), 1 << 20));
  const int used = message.decode(bytes.data(), 0, size);
  if (used < 0)
    return fail(ErrorCode::kInvalidArgument,
                "imu: %zu bytes are not an omnipose.imu_t (too short, or another type)", bytes.size());
  if (static_cast<std::size_t>(used) != bytes.size())
    return fail(ErrorCode::kInvalidArgument, "imu: %zu bytes after the omnipose.imu_t message",
                bytes.size() - static_cast<std::size_t>(used));
  if (message.utime <= 0)
    return fail(ErrorCode::kInvalidArgument, "imu: utime %lld is not a time after the clock's start",
                static_cast<long long>(message.utime));
  GyroSample sample;
  sample.t = static_cast<double>(message.utime) * 1e-6;
  for (int axis = 0; axis < 3; ++axis) {
    const double rate = message.gyro[axis];
    if (!(std::abs(rate) <= kMaxGyroRate))
      return fail(ErrorCode::kInvalidArgument,
                  "imu: gyro[%d] = %g rad/s is not a reading (finite, at most %g rad/s)", axis, rate,
                  kMaxGyroRate);
    sample.rate[axis] = rate;
  }
  return sample;
}

}  // namespace omnipose::daemon
