// A live gyro stream as Odometry keeps and reads it: arbitrary samples pushed into the buffer
// (src/imu/gyro_buffer.hpp), then a frame's rotation over its readout (FrameRotation) and the
// rotation between two instants (integrateGyro) read from what it kept. Whatever the samples
// (NaN, huge or equal times, rates at the limit, a full buffer), nothing crashes, the buffer
// stays strictly increasing, and every rotation returned is finite.
// Input: three little-endian doubles (frame time t0, a second time t1, the readout, seconds),
// then 32-byte records (t, wx, wy, wz) until the input ends.
#include <cmath>
#include <cstdint>
#include <cstring>

#include "imu/gyro_buffer.hpp"
#include "omnipose/calibration.hpp"
#include "pipeline/frame_rotation.hpp"

namespace {

double readDouble(const std::uint8_t* p) {
  double v;
  std::memcpy(&v, p, sizeof v);
  return v;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 24) return 0;
  const double t0 = readDouble(data), t1 = readDouble(data + 8);
  double readout = readDouble(data + 16);
  if (!std::isfinite(readout)) readout = 0.0;
  readout = std::fmod(readout, omnipose::SensorTiming::kMaxReadoutS);
  omnipose::imu::GyroBuffer buffer(64);
  for (std::size_t at = 24; at + 32 <= size; at += 32) {
    const omnipose::GyroSample s{readDouble(data + at),
                                 Eigen::Vector3d(readDouble(data + at + 8), readDouble(data + at + 16),
                                                 readDouble(data + at + 24))};
    (void)buffer.push(s);
  }
  const auto samples = buffer.samples();
  for (std::size_t i = 1; i < samples.size(); ++i)
    if (!(samples[i].t > samples[i - 1].t)) __builtin_trap();
  const double max_gap = omnipose::kGyroGapIntervals * buffer.typicalInterval();
  const omnipose::ImuCalibration imu;
  const Eigen::Vector3d bias(1e-3, -2e-3, 5e-4);
  omnipose::pipeline::FrameRotation rotation(readout);
  if (rotation.measure(samples, imu, bias, t0, max_gap, 0.0)) {
    for (const double s : {0.0, 0.5 * std::abs(readout), std::abs(readout), std::abs(readout) + 0.01})
      if (!rotation.turnAt(s).allFinite()) __builtin_trap();
  }
  if (const auto R = omnipose::integrateGyro(samples, imu, bias, t0, t1, max_gap))
    if (!R->allFinite()) __builtin_trap();
  if (const auto w = omnipose::gyroRateAt(samples, imu, bias, t1, max_gap))
    if (!w->allFinite()) __builtin_trap();
  return 0;
}
