#pragma once
/// \file v4l2_source.hpp
/// A FrameSource on a V4L2 capture device (a UVC webcam under a Kogeto Dot, ...), with
/// memory-mapped streaming. Formats: GREY (copied), YUYV (its luma taken), MJPG (decoded);
/// the first two are allocation-free per frame, MJPG decoding allocates inside libjpeg and
/// OpenCV.
///
/// Protocol (all through a V4l2Io, so a fake device can stand in for the kernel):
///   open(O_RDWR | O_NONBLOCK) -> QUERYCAP (device_caps: VIDEO_CAPTURE + STREAMING)
///   -> ENUM_FMT (is the format offered?) -> S_FMT (the driver's adjusted size is read back
///   and used) -> G_PARM / S_PARM (frame interval, read back) -> REQBUFS (MMAP) ->
///   QUERYBUF + mmap per buffer (mapped once) -> QBUF all -> STREAMON.
///   next(): poll(POLLIN, timeout) -> DQBUF until EAGAIN (EINTR retried) -> the newest good
///   frame is converted, every buffer is queued again.
///
/// Freshness: frames left in the queue are stale. next() drains every completed buffer
/// and delivers the newest; when *every* buffer had completed, the driver had nothing to
/// capture into and newer frames were lost, so even the newest one is old: all are
/// requeued and next() waits for a fresh frame (Options::drop_stale). The policy is the one
/// both camera drivers share (common/streaming.hpp: planDrain, SequenceTracker).
///
/// Timestamps: buffers stamped on CLOCK_MONOTONIC are converted to the wall clock with an
/// offset measured at stream start (the least-preempted of a few bracketed reads) and
/// re-measured every Options::clock_resync; other buffers get the wall time of dequeue.
///
/// Unplug: ENODEV from any call, POLLERR/POLLHUP, or a broken stream (EIO from DQBUF, a
/// failed QBUF) releases the device (fd closed, buffers unmapped and freed) and next()
/// returns kDisconnected, then keeps returning it without touching the device. The source
/// does not retry: its owner closes and opens it again when it wants to (the daemon's
/// capture loop does, with its back-off). After open() the sequence numbers continue (the
/// time away shows as a gap estimated from the frame rate).
///
/// Threading: one thread drives a source (the capture thread); stats() from that thread.

#include <chrono>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "common/clock_offset.hpp"
#include "common/streaming.hpp"
#include "omnipose/frame_source.hpp"
#include "v4l2/v4l2_io.hpp"

namespace omnipose {

/// The pixel formats V4l2Source turns into grey.
enum class V4l2PixelFormat { kGrey, kYuyv, kMjpg };

/// "GREY" (also "GRAY", "Y8"), "YUYV" (also "YUY2"), "MJPG" (also "MJPEG", "JPEG"),
/// case-insensitive; nullopt otherwise.
std::optional<V4l2PixelFormat> parseV4l2PixelFormat(std::string_view name);
/// "GREY" | "YUYV" | "MJPG".
const char* toString(V4l2PixelFormat format);

/// Everything V4l2Source needs. The first five fields are what daemon.yaml's `source:`
/// section sets (src/daemon/source_factory.cpp maps them, the key is named beside each);
/// the rest is tuning, not in daemon.yaml, with defaults for a 30 fps USB camera.
struct V4l2Options {
  std::string device = "/dev/video0";  ///< source.device: the capture node's path
  int width = 1280;                    ///< source.width: requested, pixels, [1, 16384]
  int height = 720;                    ///< source.height: requested, pixels, [1, 16384]
  double fps = 30.0;                   ///< source.fps: requested, frames/s, (0, 1000]
  std::string format = "YUYV";         ///< source.format: parseV4l2PixelFormat()

  int buffer_count = 4;  ///< buffers requested with REQBUFS, [2, 32] (the driver may grant more)
  std::chrono::milliseconds clock_resync{10000};     ///< re-measure the clock offset, >= 1
  int clock_samples = 7;   ///< bracketed reads per measurement, [1, 16]
  bool drop_stale = true;  ///< see the file comment ("Freshness")
  /// The calibration's sensor.readout_s (seconds, a rolling shutter; 0 = global): a buffer
  /// the driver stamps at the end of the frame (V4L2_BUF_FLAG_TSTAMP_SRC_EOF) is dated
  /// |readout_s| earlier, at its first row's capture, the frame timestamp of DESIGN.md
  /// section 2. Start-of-exposure stamps are kept. |readout_s| <= 0.1.
  double readout_s = 0.0;
};

/// Every problem of `options`, without touching any device (empty = valid). The daemon's
/// fields are named by their daemon.yaml key ("source.format: 'XYZ' is not ..."), the
/// tuning fields by their name ("buffer_count: must be in [2, 32], is 1").
std::vector<std::string> validate(const V4l2Options& options);

class V4l2Source final : public FrameSource {
 public:
  using Options = V4l2Options;

  /// Counters since construction (they survive close() and open()).
  struct Stats {
    std::uint64_t delivered = 0;        ///< frames returned by next()
    std::uint64_t stale_dropped = 0;    ///< good frames drained from the queue, not delivered
    std::uint64_t error_flagged = 0;    ///< buffers flagged V4L2_BUF_FLAG_ERROR, dropped
    std::uint64_t bad_frames = 0;       ///< too short or undecodable, dropped
    std::uint64_t lost_upstream = 0;    ///< frames the driver dropped (sequence gaps in DQBUF)
    std::uint64_t interrupted = 0;      ///< calls retried after EINTR
    std::uint64_t disconnects = 0;      ///< unplugs / stream failures seen
  };

  /// What open() agreed with the driver.
  struct Negotiated {
    cv::Size size;                  ///< frame size delivered (the driver's, after S_FMT)
    cv::Size requested;             ///< what the options asked for
    V4l2PixelFormat format = V4l2PixelFormat::kYuyv;
    std::uint32_t fourcc = 0;       ///< the V4L2 pixel format in use (MJPG may be JPEG)
    std::uint32_t bytes_per_line = 0;
    std::uint32_t image_bytes = 0;  ///< sizeimage
    double fps = 0.0;               ///< from the frame interval; 0 = the driver cannot tell
    double requested_fps = 0.0;
    int buffers = 0;                ///< granted by REQBUFS
    std::string driver;             ///< QUERYCAP driver name
    std::string card;               ///< QUERYCAP card name
  };

  /// `io`: borrowed, must outlive the source; nullptr = the real kernel. The options are
  /// checked by open() (validate()).
  explicit V4l2Source(Options options, V4l2Io* io = nullptr);
  ~V4l2Source() override;
  V4l2Source(const V4l2Source&) = delete;
  V4l2Source& operator=(const V4l2Source&) = delete;

  /// Opens, negotiates and starts streaming. Errors: kInvalidArgument (validate() failed;
  /// the first problem is named), kNotFound (no such path), kNoDevice (not a V4L2 capture
  /// node / gone), kBusy, kUnsupportedFormat (format not offered, replaced by the driver,
  /// interlaced), kIoError (permissions, a failing ioctl). Messages name the device.
  Expected<void> open() override;
  cv::Size frameSize() const override { return negotiated_.size; }
  /// See FrameSource::next(). Also kInvalidArgument when `out` is not frameSize() CV_8UC1
  /// or the source is not open.
  Expected<FrameInfo> next(cv::Mat& out, std::chrono::milliseconds timeout) override;
  void close() override;
  std::string describe() const override;

  const Stats& stats() const { return stats_; }
  const Negotiated& negotiated() const { return negotiated_; }
  /// The CLOCK_MONOTONIC -> CLOCK_REALTIME offset in use.
  const drivers::ClockOffset& clockOffset() const { return clock_offset_; }
  /// True between an unplug (or stream failure) and the next close() or open().
  bool disconnected() const { return state_ == State::kDisconnected; }

 private:
  enum class State { kClosed, kStreaming, kDisconnected };
  enum class Step { kDelivered, kRetry, kFailed };

  struct Buffer {
    void* data = nullptr;
    std::size_t length = 0;
    bool queued = false;
  };
  struct Dequeued {
    std::uint32_t index = 0;
    std::uint32_t sequence = 0;
    std::uint32_t bytes_used = 0;
    std::uint32_t flags = 0;
    std::int64_t timestamp_ns = 0;
  };

  Expected<void> start();
  void teardown();
  Expected<void> negotiateFormat();
  void negotiateFrameRate();
  Expected<void> setUpBuffers();
  Step drain(cv::Mat& out, FrameInfo& info, Error& error);
  Expected<void> convert(const Dequeued& d, cv::Mat& out);
  bool requeue(std::uint32_t index);
  Error disconnect(const char* what, int err);
  void resyncClock();
  int xioctl(unsigned long request, void* arg);
  std::int64_t nowNs(clockid_t clock);

  Options options_;
  V4l2Io* io_;
  State state_ = State::kClosed;
  int fd_ = -1;
  bool streaming_ = false;
  bool buffers_requested_ = false;
  std::vector<Buffer> buffers_;
  std::vector<Dequeued> dequeued_;  // reserved at open: drain() never allocates
  int queued_count_ = 0;
  Negotiated negotiated_;
  std::string describe_;
  cv::Mat jpeg_scratch_;

  drivers::ClockOffset clock_offset_;
  std::int64_t last_clock_sync_ns_ = 0;

  drivers::SequenceTracker sequence_;

  Stats stats_;
};

}  // namespace omnipose
