#pragma once
/// \file daemon.hpp
/// omniposed's core: start-up (calibration, pipeline, frame source, LCM, every buffer),
/// then two threads: capture (FrameSource -> latest-frame mailbox) and processing
/// (mailbox -> pipeline -> pose chain -> LCM pose per processed frame, status at
/// lcm.status_hz). After start() the per-frame path allocates nothing (DESIGN.md section 5).
///
/// Life cycle: construct (throws on any start-up problem, with a message naming the file,
/// key or device; a camera or LCM log that another omniposed holds is refused with its
/// PID, instance_lock.hpp) -> start() -> either requestStop() (signal) or the source ends (a finite
/// file source: finished() becomes true after the last frame's pose) -> join(), which joins
/// both threads and publishes the final status (status_t.final = true).
///
/// Process-wide side effect: the constructor sets OpenCV's thread count to 1 (the daemon
/// has its own two threads; OpenCV's pool would allocate per parallel call).
///
/// Replay policy: a file source with `realtime: false` is replayed losslessly (the capture
/// thread reads the next frame only when the processor took the last one: "as fast as
/// possible" is as fast as the pipeline); every other source drops stale frames.

#include <chrono>
#include <atomic>
#include <condition_variable>
#include <cstdio>
#include <memory>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "daemon/capture_loop.hpp"
#include "daemon/frame_mailbox.hpp"
#include "daemon/gyro_queue.hpp"
#include "daemon/gyro_stream.hpp"
#include "daemon/message_sink.hpp"
#include "daemon/processor.hpp"
#include "daemon/status_board.hpp"
#include "daemon/config.hpp"
#include "omnipose/file_io.hpp"
#include "omnipose/frame_source.hpp"

namespace omnipose {
class IioIo;  // drivers/iio/iio_io.hpp
}  // namespace omnipose

namespace omnipose::daemon {

/// What the constructor is doing, for a stop requested during start-up (runService()).
/// Written by the constructor, read from another thread: a static string each.
using StartupPhase = std::atomic<const char*>;

/// Knobs that are not part of daemon.yaml (tests, tools).
struct DaemonOptions {
  CaptureLoop::Options capture;
  /// Replay lossless even if the source is not a non-realtime file source (tests).
  bool force_lossless = false;
  /// Updated with what start-up is doing ("loading the calibration", ...); may be null.
  StartupPhase* phase = nullptr;
  /// imu.source iio: the kernel calls (nullptr = the kernel's own, SystemIioIo; borrowed,
  /// must outlive the daemon) and where the devices are ("" = /sys/bus/iio/devices, /dev).
  IioIo* iio_io = nullptr;
  std::string iio_sysfs_root;
  std::string iio_dev_root;
};

class Daemon {
 public:
  using Options = DaemonOptions;

  /// Start-up. `source`/`sink` replace the configured ones when given (tests); the source
  /// is opened here. `log` (borrowed) receives start-up, fault and shutdown lines.
  /// Throws std::runtime_error (or ConfigError/CalibrationError, both runtime_errors)
  /// on any start-up problem.
  Daemon(const DaemonConfig& config, std::FILE* log,
         std::unique_ptr<FrameSource> source = nullptr,
         std::unique_ptr<MessageSink> sink = nullptr, DaemonOptions options = {});
  /// Stops and joins if still running.
  ~Daemon();
  Daemon(const Daemon&) = delete;
  Daemon& operator=(const Daemon&) = delete;

  /// Starts the capture and processing threads.
  void start();
  /// Asks both threads to stop (thread-safe, returns at once; not async-signal-safe).
  void requestStop();
  /// True once the processing thread has finished (end of stream or stop).
  bool finished() const;
  /// Waits up to `timeout` for finished().
  bool waitFinished(std::chrono::milliseconds timeout);
  /// Joins both threads and publishes the final status (once). Idempotent.
  void join();

  /// Counters so far (thread-safe, allocation-free).
  DaemonStats stats() const;
  /// Whether both threads made progress within `max_silence` (for the systemd watchdog).
  bool alive(std::chrono::nanoseconds max_silence) const { return board_.alive(max_silence); }
  /// One line each: the source and the LCM transport.
  const std::string& sourceDescription() const { return source_description_; }
  /// What the source noticed when it was opened (FrameSource::warnings()).
  const std::vector<std::string>& sourceWarnings() const { return source_warnings_; }
  std::string sinkDescription() const { return sink_->describe(); }
  /// One line on the gyro's stream ("" without one: daemon.yaml imu.source none).
  std::string imuDescription() const { return imu_ ? imu_->describe() : std::string(); }

 private:
  void processLoop();
  /// The gyro's stream of daemon.yaml `imu` (none: nullptr); throws on a start-up problem.
  std::unique_ptr<GyroStream> makeGyroStream();

  DaemonConfig config_;
  Options options_;
  std::FILE* log_;
  StatusBoard board_;
  std::unique_ptr<FrameSource> source_;
  std::unique_ptr<MessageSink> sink_;
  std::unique_ptr<FrameMailbox> mailbox_;
  std::unique_ptr<GyroQueue> gyro_queue_;
  std::unique_ptr<GyroStream> imu_;
  std::unique_ptr<Processor> processor_;
  std::unique_ptr<CaptureLoop> capture_;
  std::string source_description_;
  std::vector<std::string> source_warnings_;
  FileLock source_lock_;

  std::thread capture_thread_;
  std::thread process_thread_;
  mutable std::mutex done_mutex_;
  std::condition_variable done_cv_;
  bool processing_done_ = false;
  bool started_ = false;
  bool joined_ = false;
};

}  // namespace omnipose::daemon
