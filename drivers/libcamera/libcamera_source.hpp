#pragma once
/// \file libcamera_source.hpp
/// A FrameSource on a libcamera camera (Raspberry Pi camera modules, UVC cameras through
/// libcamera's uvcvideo pipeline), written for Debian 12's libcamera 0.0.3 and guarded for
/// later versions (libcamera_compat.hpp). No libcamera header leaks through this one:
/// the source talks to libcamera through the seam of libcamera_camera.hpp
/// (libcamera_real.cpp adapts libcamera; tests run the same code on a fake).
///
/// open(): the process-wide CameraManager (libcamera allows one) -> the camera by index or
/// id -> acquire -> one VideoRecording stream in a grey-convertible format (chooseFormat():
/// the configured one when offered, else the best offered) at the configured size, read
/// back after validate() -> configure -> FrameBufferAllocator -> one Request per buffer,
/// every buffer's planes mmap-ed once -> start with FrameDurationLimits = 1 / fps ->
/// queue every request.
///
/// next(): the completion callback (libcamera's thread) only hands the finished request's
/// result (libcam::Completion) to the capture thread through a fixed-capacity queue; next() takes the newest, requeues
/// the older ones (stale), converts (luma plane copy / packed luma / JPEG decode) into the
/// caller's buffer and requeues. Timestamps: controls::SensorTimestamp (ns, CLOCK_BOOTTIME;
/// the buffer's timestamp when absent) + a measured CLOCK_BOOTTIME -> CLOCK_REALTIME offset.
/// Our per-frame code allocates nothing for luma/packed formats; libcamera itself allocates
/// inside Request::reuse()/queueRequest().
///
/// Unplug: the camera's `disconnected` signal (or a failed requeue) releases the camera
/// (stopped, buffers unmapped and freed, released) and next() returns kDisconnected, then
/// keeps returning it without touching libcamera. The source does not retry: its owner
/// closes and opens it again when it wants to (the daemon's capture loop does, with its
/// back-off); after open() the sequence numbers continue across the time away. Draining and
/// sequence numbers follow the policy both camera drivers share (common/streaming.hpp).
///
/// Threading: one capture thread calls open/next/close; the callbacks run on libcamera's
/// thread and only touch the hand-over queue.

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/frame_source.hpp"

namespace omnipose {
namespace libcam {
class CameraManager;
}

/// Everything LibcameraSource needs. The first five fields are what daemon.yaml's
/// `source:` section sets (src/daemon/source_factory.cpp maps them, the key is named beside
/// each); the rest is tuning, not in daemon.yaml.
struct LibcameraOptions {
  std::string camera = "0";  ///< source.camera: an index ("0", "1", ...) or a libcamera id
  int width = 1280;          ///< source.width: requested, pixels, [1, 16384]
  int height = 720;          ///< source.height: requested, pixels, [1, 16384]
  double fps = 30.0;         ///< source.fps: requested, frames/s, (0, 1000]
  /// source.format: a grey-convertible format (libcam::parseFormatName(): R8/GREY, NV12,
  /// YUV420, YUYV, UYVY, MJPEG, ...), or "auto" / "" for the best the camera offers.
  std::string format = "auto";

  int buffer_count = 4;                              ///< requests / buffers in flight, [1, 32]
  std::chrono::milliseconds clock_resync{10000};     ///< re-measure the clock offset, >= 1
  /// Bracketed clock reads (CLOCK_BOOTTIME, CLOCK_REALTIME, CLOCK_BOOTTIME) per offset
  /// measurement, [1, 16] (drivers::kMaxClockSamples): the least preempted read wins, so
  /// more samples make a preempted measurement less likely; each costs three clock reads.
  int clock_samples = 7;
  bool drop_stale = true;  ///< when every request had completed, wait for a fresh frame
  /// The calibration's sensor timing: each frame's stamp (SensorTimestamp) is moved to its
  /// first row's capture time by SensorTiming::captureTimeOffset() of the exposure the
  /// camera reported for it (ExposureTime), or of `sensor.exposure_s` when it reported none;
  /// the reported exposure goes on in FrameInfo::exposure_s.
  SensorTiming sensor;
};

/// Every problem of `options`, without touching libcamera (empty = valid). The daemon's
/// fields are named by their daemon.yaml key ("source.camera: ..."), the tuning fields by
/// their name ("buffer_count: must be in [1, 32], is 0").
std::vector<std::string> validate(const LibcameraOptions& options);

class LibcameraSource final : public FrameSource {
 public:
  using Options = LibcameraOptions;

  struct Stats {
    std::uint64_t delivered = 0;
    std::uint64_t stale_dropped = 0;   ///< completed frames requeued without delivery
    std::uint64_t error_frames = 0;    ///< FrameMetadata status error / cancelled
    std::uint64_t bad_frames = 0;      ///< too short or undecodable
    std::uint64_t lost_upstream = 0;   ///< gaps in the buffers' sequence numbers
    std::uint64_t disconnects = 0;     ///< unplugs / failed requeues seen
  };

  /// Returns the started camera manager; open() calls it.
  using ManagerOpener =
      std::function<Expected<std::shared_ptr<libcam::CameraManager>>()>;

  /// On libcamera (the process-wide CameraManager). The options are checked by open()
  /// (validate()).
  explicit LibcameraSource(Options options);
  /// On the manager `opener` gives (a fake in tests).
  LibcameraSource(Options options, ManagerOpener opener);
  ~LibcameraSource() override;
  LibcameraSource(const LibcameraSource&) = delete;
  LibcameraSource& operator=(const LibcameraSource&) = delete;

  /// The libcamera version this was built against ("0.0.3").
  static std::string libcameraVersion();

  /// Errors: kInvalidArgument (validate() failed; the first problem is named), kNoDevice ("no camera" / index out of
  /// range), kNotFound (unknown id), kBusy (acquired elsewhere), kUnsupportedFormat,
  /// kIoError (allocation, mapping, start).
  Expected<void> open() override;
  cv::Size frameSize() const override;
  Expected<FrameInfo> next(cv::Mat& out, std::chrono::milliseconds timeout) override;
  void close() override;
  std::string describe() const override;

  const Stats& stats() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace omnipose
