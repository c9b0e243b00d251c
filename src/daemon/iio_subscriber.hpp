#pragma once
/// \file iio_subscriber.hpp
/// The robot's gyro read from a Linux IIO device (daemon.yaml `imu: {source: iio, device,
/// sampling_hz}`): a thread of its own reads its scans (IioGyro, drivers/iio/iio_gyro.hpp;
/// times on CLOCK_MONOTONIC, the frames' clock) and queues the samples for the processing
/// thread (GyroQueue).
///
/// Faults are counted on the StatusBoard and reported (rate-limited), never fatal after
/// start-up: scans the reader skipped (imu_messages_bad), a sample that finds the queue full
/// (imu_samples_dropped), and the device going away or failing (imu_device_lost, once per
/// outage): it is
/// then closed and opened again every kRetryInterval, looked up by name again (its index may
/// have changed), until it is back or the daemon stops; meanwhile the pipeline goes on from
/// the images alone.
///
/// Realtime: the constructor and re-opening allocate; reading allocates nothing.

#include <array>
#include <chrono>
#include <memory>
#include <string>

#include "daemon/gyro_queue.hpp"
#include "daemon/gyro_stream.hpp"
#include "daemon/status_board.hpp"
#include "iio/iio_gyro.hpp"

namespace omnipose::daemon {

class IioSubscriber final : public GyroStream {
 public:
  /// How often a device that went away is looked for again.
  static constexpr std::chrono::milliseconds kRetryInterval{500};

  /// Opens the device (IioGyro::open()). Throws std::runtime_error naming daemon.yaml's
  /// imu.device and the device ("imu.device: iio device \"bmi160\": no device of that
  /// name under /sys/bus/iio/devices") when it cannot. `io`, `queue` and `board` are
  /// borrowed and must outlive this. Warnings of open() are logged on `board`.
  IioSubscriber(const IioGyroOptions& options, IioIo& io, GyroQueue& queue, StatusBoard& board);
  /// Stops and joins the thread; disables the device's buffer and closes it.
  ~IioSubscriber() override;

  /// "imu: iio:device0 (bmi160), anglvel x,y,z le:s16/16>>0 x 0.000266 rad/s, ..."
  std::string describe() const override { return description_; }

 private:
  void run() override;
  void readOnce();
  void reopen(const Error& why);
  /// Sleeps `duration` in pieces short enough to notice stop(); false when stopped.
  bool sleepFor(std::chrono::milliseconds duration);

  IioIo& io_;
  GyroQueue& queue_;
  StatusBoard& board_;
  IioGyro gyro_;
  std::string description_;
  std::array<GyroSample, IioGyro::kMaxScansPerRead> samples_{};
};

}  // namespace omnipose::daemon
