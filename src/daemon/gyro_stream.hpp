#pragma once
/// \file gyro_stream.hpp
/// Where the daemon's gyro samples come from (daemon.yaml `imu.source`): a thread of its own
/// that fills the GyroQueue the processing thread empties before each frame, and counts its
/// faults on the StatusBoard. Two kinds: ImuSubscriber (LCM, imu_subscriber.hpp) and
/// IioSubscriber (a Linux IIO gyro, iio_subscriber.hpp). Constructing one is the start-up
/// (it throws on a start-up problem); after start() nothing it meets is fatal.
///
/// The thread is this class's: start() runs the kind's run() on it, stop() asks run() to
/// return (stopRequested()) and joins it. A kind's destructor calls stop() first, since run()
/// uses the kind's members.

#include <atomic>
#include <string>
#include <thread>

namespace omnipose::daemon {

class GyroStream {
 public:
  /// The kind's destructor has stopped the thread already; this joins it if it has not.
  virtual ~GyroStream() { stop(); }
  GyroStream() = default;
  GyroStream(const GyroStream&) = delete;
  GyroStream& operator=(const GyroStream&) = delete;

  /// Starts the thread (once; not again after stop()).
  void start() {
    if (!thread_.joinable() && !stop_.load()) thread_ = std::thread([this] { run(); });
  }
  /// Stops and joins the thread (idempotent; within about 50 ms: run() looks that often).
  void stop() {
    stop_.store(true);
    if (thread_.joinable()) thread_.join();
  }
  /// One line for the start-up log.
  virtual std::string describe() const = 0;

 protected:
  /// The thread's body: receives until stopRequested(), looking at least every 50 ms.
  virtual void run() = 0;
  bool stopRequested() const { return stop_.load(); }

 private:
  std::thread thread_;
  std::atomic<bool> stop_{false};
};

}  // namespace omnipose::daemon
