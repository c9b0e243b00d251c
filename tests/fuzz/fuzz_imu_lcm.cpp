// omnipose.imu_t bytes as an LCM subscriber receives them (omnipose::daemon::decodeImuMessage):
// either an error naming the message, or a sample with a positive time and a finite rate
// within kMaxGyroRate. The input is the message's bytes.
#include <cmath>
#include <cstdint>
#include <span>
#include <string_view>

#include "daemon/imu_message.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto r = omnipose::daemon::decodeImuMessage(std::span(data, size));
  if (!r) {
    if (r.error().message().substr(0, 5) != "imu: ") __builtin_trap();
    return 0;
  }
  if (!(r->t > 0.0) || !r->rate.allFinite()) __builtin_trap();
  if (!(r->rate.cwiseAbs().maxCoeff() <= omnipose::kMaxGyroRate)) __builtin_trap();
  return 0;
}
