#pragma once
/// \file gyro_stream.hpp
/// Where the daemon's gyro samples come from (daemon.yaml `imu.source`): a thread of its own
/// that fills the GyroQueue the processing thread empties before each frame, and counts its
/// faults on the StatusBoard. Two kinds: ImuSubscriber (LCM, imu_subscriber.hpp) and
/// IioSubscriber (a Linux IIO gyro, iio_subscriber.hpp). Constructing one is the start-up
/// (it throws on a start-up problem); after start() nothing it meets is fatal.

#include <string>

namespace omnipose::daemon {

class GyroStream {
 public:
  virtual ~GyroStream() = default;
  /// Starts the thread (once).
  virtual void start() = 0;
  /// Stops and joins the thread (idempotent; within about 50 ms).
  virtual void stop() = 0;
  /// One line for the start-up log.
  virtual std::string describe() const = 0;
};

}  // namespace omnipose::daemon
