#pragma once
/// \file fake_v4l2_device.hpp
/// A V4L2 capture device in user space, behind the V4l2Io seam, that follows the kernel's
/// protocol (videobuf2 + uvcvideo behaviour) strictly enough that a driver passing against
/// it would work on a real camera:
///
/// - open(): ENOENT when the node is missing (unplugged); per-fd O_NONBLOCK.
/// - QUERYCAP with capabilities | V4L2_CAP_DEVICE_CAPS and per-node device_caps.
/// - ENUM_FMT until EINVAL; S_FMT/TRY_FMT adjust the size (step-wise or UVC-like discrete
///   sizes), pad bytesperline, set sizeimage; an unsupported pixel format is replaced by
///   the first supported one (the specification) or answered with EINVAL (old drivers);
///   S_FMT/REQBUFS give EBUSY while buffers exist, while streaming, or when another
///   process owns the queue.
/// - G_PARM/S_PARM pick the nearest offered frame interval (or ENOTTY when not settable).
/// - REQBUFS (MMAP only) clamps the count; QUERYBUF gives offsets; mmap must match an
///   offset and length with MAP_SHARED; munmap must match a mapping.
/// - QBUF rejects an index out of range or a buffer that is not dequeued (EINVAL); a
///   queued buffer is scribbled over, so reading it after QBUF shows up as wrong pixels.
/// - STREAMON needs buffers; frames complete into queued buffers in FIFO order at the
///   frame interval on a virtual CLOCK_MONOTONIC; with no buffer queued a frame is lost
///   (the sequence counter still advances).
/// - DQBUF: EINVAL when not streaming, EAGAIN when nothing is done (O_NONBLOCK; a blocking
///   DQBUF that would sleep is a violation), flags DONE / ERROR / MAPPED / timestamp type.
/// - poll: POLLIN|POLLRDNORM when a buffer is done, POLLERR when not streaming, POLLNVAL for
///   a bad fd; waiting advances the virtual clock to the next frame or the timeout.
/// - Unplug: every ioctl and mmap on an old fd gives ENODEV, poll gives
///   POLLERR|POLLHUP|POLLPRI, open() gives ENOENT until replug; munmap/close still work.
/// - Injected errors: any ioctl or poll can be made to fail with EINTR (a signal) etc.
///
/// Time is virtual: poll() and sleeps jump to the next event, clock reads cost a little,
/// so tests run fast and exactly. Everything the driver does wrong is recorded in
/// violations(); tests assert it stays empty.

#include <linux/videodev2.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "v4l2/v4l2_io.hpp"

namespace omnipose::testing {

enum class FakeUnsupportedFormatPolicy { kReplace, kEinval };

struct FakeV4l2Config {
  std::string path = "/dev/video0";
  std::string card = "Fake Omni Camera";
  std::uint32_t device_caps = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_STREAMING;
  /// Offered pixel formats, in ENUM_FMT order.
  std::vector<std::uint32_t> formats = {V4L2_PIX_FMT_YUYV, V4L2_PIX_FMT_GREY,
                                        V4L2_PIX_FMT_MJPEG};
  FakeUnsupportedFormatPolicy unsupported_format = FakeUnsupportedFormatPolicy::kReplace;
  /// Step-wise sizes: rounded to the nearest multiple of size_step, clamped.
  int size_step = 16;
  cv::Size min_size{32, 32};
  cv::Size max_size{1920, 1088};
  /// Non-empty: UVC-like discrete sizes, the closest one is chosen (overrides steps).
  std::vector<cv::Size> discrete_sizes;
  /// bytesperline is rounded up to a multiple of this (row padding).
  std::uint32_t stride_align = 1;
  /// Offered frame rates (first = default); S_PARM picks the nearest interval.
  std::vector<int> frame_rates = {30, 15};
  bool frame_rate_settable = true;
  std::uint32_t min_buffers = 2;
  std::uint32_t max_buffers = 8;
  /// Timestamp type in the buffer flags (MONOTONIC, or COPY / UNKNOWN).
  std::uint32_t timestamp_type = V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
  /// What a monotonic timestamp marks: the start of exposure (SOE) or the end of the
  /// frame (EOF); frameTimestampNs() is the buffer's timestamp either way.
  std::uint32_t timestamp_source = V4L2_BUF_FLAG_TSTAMP_SRC_SOE;
  int jpeg_quality = 100;
  /// Distinct frames rendered at STREAMON and shown in turn (frame k shows k % cycle).
  int content_cycle = 8;
  std::int64_t clock_read_cost_ns = 40;
  std::int64_t start_monotonic_ns = 5'000'000'000'000;  // 5000 s of uptime
  std::int64_t realtime_offset_ns = 1'700'000'000'123'456'789;
};

class FakeV4l2Device final : public V4l2Io {
 public:
  using UnsupportedFormatPolicy = FakeUnsupportedFormatPolicy;
  using Config = FakeV4l2Config;

  /// Content of frame k at the negotiated size: CV_8UC1 (GREY/YUYV/MJPG) or CV_8UC3 (MJPG).
  using Content = std::function<cv::Mat(std::uint64_t frame, cv::Size size)>;

  explicit FakeV4l2Device(Config config = {});
  ~FakeV4l2Device() override;

  // ---- scripting --------------------------------------------------------------------
  void setContent(Content content);
  /// The default content: a pattern that differs per frame and per pixel.
  static cv::Mat patternFrame(std::uint64_t frame, cv::Size size);
  /// Another process holds the device: S_FMT and REQBUFS give EBUSY.
  void setBusy(bool busy) { busy_ = busy; }
  /// The camera stops delivering frames (true) or resumes (false).
  void setStalled(bool stalled);
  /// The camera stops after this many frames in all (across streams and replugs).
  void stallAfter(std::uint64_t frames) { stall_after_ = frames; }
  /// Scripted hotplug: after `failures` more failed open() attempts while unplugged, the
  /// device is back for the next attempt.
  void replugAfterFailedOpens(int failures) { replug_after_failed_opens_ = failures; }
  /// Frame `sequence` completes with V4L2_BUF_FLAG_ERROR (content still written).
  void flagError(std::uint64_t sequence) { error_frames_.push_back(sequence); }
  /// Frame `sequence` completes with only `bytes` bytes used.
  void truncate(std::uint64_t sequence, std::uint32_t bytes) {
    truncated_frames_.push_back({sequence, bytes});
  }
  /// Frame `sequence` carries garbage instead of its encoding.
  void corrupt(std::uint64_t sequence) { corrupt_frames_.push_back(sequence); }
  /// The next `count` calls of ioctl `request` fail with `err` (EINTR, EIO, ...).
  void injectIoctlError(unsigned long request, int err, int count = 1);
  /// The next `count` poll() calls fail with `err` after `after_ms` of waiting.
  void injectPollError(int err, int count = 1, int after_ms = 1);
  /// The device node disappears now / comes back now.
  void unplug();
  void replug();
  /// ... or at a virtual CLOCK_MONOTONIC time (ns); 0 cancels.
  void scheduleUnplug(std::int64_t at_ns) { unplug_at_ns_ = at_ns; }
  void scheduleReplug(std::int64_t at_ns) { replug_at_ns_ = at_ns; }
  /// The consumer is busy for `ns`: time passes, frames arrive.
  void advance(std::int64_t ns);
  /// Steps the wall clock (an NTP correction).
  void stepRealtime(std::int64_t ns) { config_.realtime_offset_ns += ns; }
  /// Every `every`-th CLOCK_REALTIME read is preceded by a `delay_ns` stall (preemption
  /// between the bracketing reads). every = 0 turns it off.
  void delayRealtimeReads(int every, std::int64_t delay_ns) {
    realtime_delay_every_ = every;
    realtime_delay_ns_ = delay_ns;
  }

  // ---- inspection -------------------------------------------------------------------
  std::int64_t now() const { return now_ns_; }
  std::int64_t realtimeOffset() const { return config_.realtime_offset_ns; }
  const std::vector<std::string>& violations() const { return violations_; }
  int openFdCount() const;
  int mappingCount() const { return static_cast<int>(mappings_.size()); }
  bool streaming() const { return streaming_; }
  bool plugged() const { return plugged_; }
  /// Frames completed into a buffer / lost for want of a queued buffer (this stream).
  std::uint64_t framesProduced() const { return produced_; }
  std::uint64_t framesLost() const { return lost_; }
  /// Kernel sequence of the next frame (frames so far in this stream).
  std::uint64_t sequenceCounter() const { return sequence_; }
  /// CLOCK_MONOTONIC time of frame `sequence` of the current stream (ns), as stamped
  /// (truncated to microseconds, like a timeval), or -1.
  std::int64_t frameTimestampNs(std::uint64_t sequence) const;
  /// The grey image frame `sequence` of the current stream should convert to.
  cv::Mat expectedGrey(std::uint64_t sequence) const;
  /// Content index (the `frame` argument of Content, before % content_cycle) of the frame
  /// stamped at CLOCK_MONOTONIC `timestamp_ns` (as frameTimestampNs), in any stream; -1.
  /// The content runs on across streams: a replugged camera shows the scene going on.
  std::int64_t contentIndexAt(std::int64_t timestamp_ns) const;
  /// The negotiated format (valid after S_FMT).
  const v4l2_pix_format& format() const { return format_; }
  std::uint32_t bufferCount() const { return static_cast<std::uint32_t>(buffers_.size()); }
  /// Virtual times of every open() attempt on the path.
  const std::vector<std::int64_t>& openAttempts() const { return open_attempts_; }
  int pollCalls() const { return poll_calls_; }
  int streamOnCount() const { return streamon_count_; }
  /// The last timeperframe set (fps = denominator / numerator).
  v4l2_fract timePerFrame() const { return time_per_frame_; }

  // ---- V4l2Io -----------------------------------------------------------------------
  int open(const char* path, int flags) override;
  int close(int fd) override;
  int ioctl(int fd, unsigned long request, void* arg) override;
  int poll(pollfd* fds, nfds_t nfds, int timeout_ms) override;
  void* mmap(void* addr, std::size_t length, int prot, int flags, int fd,
             off_t offset) override;
  int munmap(void* addr, std::size_t length) override;
  int clockGettime(clockid_t clock, timespec* ts) override;

 private:
  enum class BufState { kDequeued, kQueued, kDone };
  struct Buffer {
    std::shared_ptr<std::uint8_t[]> storage;
    std::uint32_t length = 0;
    std::uint32_t offset = 0;
    BufState state = BufState::kDequeued;
    std::uint32_t bytes_used = 0;
    std::uint32_t flags = 0;
    std::uint32_t sequence = 0;
    timeval timestamp{};
  };
  struct Mapping {
    void* addr = nullptr;
    std::size_t length = 0;
    std::shared_ptr<std::uint8_t[]> storage;
  };
  struct Fd {
    int fd = -1;
    int generation = 0;
    bool nonblocking = false;
  };
  struct Injection {
    unsigned long request = 0;  // 0: poll
    int err = 0;
    int remaining = 0;
    int after_ms = 0;
  };
  /// A fixed-capacity FIFO of buffer indices (no allocation while streaming).
  struct Fifo {
    std::uint32_t items[64] = {};
    int head = 0, count = 0;
    void push(std::uint32_t v) { items[(head + count++) % 64] = v; }
    std::uint32_t pop() {
      const std::uint32_t v = items[head];
      head = (head + 1) % 64;
      --count;
      return v;
    }
    void clear() { head = count = 0; }
    bool empty() const { return count == 0; }
  };

  Fd* findFd(int fd);
  bool alive(const Fd& f) const { return plugged_ && f.generation == generation_; }
  int consumeInjection(unsigned long request);
  int fail(int err) const;
  void violation(std::string text);
  void resetDeviceState();
  void adjustFormat(v4l2_pix_format& pix) const;
  std::int64_t nextEventNs() const;
  void advanceTo(std::int64_t t_ns);
  void produceFrame();
  void renderContent();
  std::vector<std::uint8_t> encode(const cv::Mat& content) const;
  short readiness(const Fd& f) const;
  void freeBuffers();
  int doIoctl(Fd& f, unsigned long request, void* arg);

  Config config_;
  Content content_;
  std::int64_t now_ns_;
  bool plugged_ = true;
  int generation_ = 1;
  int next_fd_ = 100;
  std::vector<Fd> fds_;
  std::vector<Mapping> mappings_;
  std::vector<Injection> injections_;
  std::vector<std::string> violations_;
  std::vector<std::int64_t> open_attempts_;
  bool busy_ = false;

  // Device (queue) state; reset by replug.
  v4l2_pix_format format_{};
  v4l2_fract time_per_frame_{1, 30};
  std::vector<Buffer> buffers_;
  int queue_owner_ = -1;
  bool streaming_ = false;
  Fifo queued_;
  Fifo done_;
  std::uint64_t sequence_ = 0;
  std::uint64_t produced_ = 0;
  std::uint64_t lost_ = 0;
  std::int64_t next_frame_ns_ = 0;
  bool stalled_ = false;
  std::uint64_t stall_after_ = UINT64_MAX;
  std::vector<std::vector<std::uint8_t>> encoded_;  // per content-cycle slot
  std::vector<std::int64_t> frame_times_;           // per sequence of this stream
  std::uint64_t content_base_ = 0;  // content index of this stream's frame 0
  std::vector<std::pair<std::int64_t, std::uint64_t>> history_;  // (timestamp, content)
  int replug_after_failed_opens_ = -1;
  std::int64_t unplug_at_ns_ = 0;
  std::int64_t replug_at_ns_ = 0;
  std::uint64_t realtime_reads_ = 0;
  int realtime_delay_every_ = 0;
  std::int64_t realtime_delay_ns_ = 0;
  int poll_calls_ = 0;
  int streamon_count_ = 0;

  std::vector<std::uint64_t> error_frames_;
  std::vector<std::pair<std::uint64_t, std::uint32_t>> truncated_frames_;
  std::vector<std::uint64_t> corrupt_frames_;
};

}  // namespace omnipose::testing
