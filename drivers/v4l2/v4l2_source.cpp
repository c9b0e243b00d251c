#include "v4l2/v4l2_source.hpp"

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <cmath>
#include <cstring>
#include <fcntl.h>
#include <linux/videodev2.h>
#include <sstream>
#include <sys/mman.h>

#include "common/grey_convert.hpp"
#include "common/streaming.hpp"
#include "omnipose/calibration.hpp"
#include "omnipose/limits.hpp"

namespace omnipose {
namespace {

constexpr std::int64_t kNsPerMs = 1'000'000;
constexpr int kMaxEintrRetries = 1000;  // a signal storm, not a device, beyond this
constexpr int kMaxEnumFormats = 64;

/// "YUYV" from a fourcc; non-printable bytes become '?'.
struct FourccText {
  char text[5];
  explicit FourccText(std::uint32_t fourcc) {
    for (int i = 0; i < 4; ++i) {
      const char c = static_cast<char>((fourcc >> (8 * i)) & 0xFF);
      text[i] = (c >= 32 && c < 127) ? c : '?';
    }
    text[4] = '\0';
  }
};

std::uint32_t primaryFourcc(V4l2PixelFormat format) {
  switch (format) {
    case V4l2PixelFormat::kGrey: return V4L2_PIX_FMT_GREY;
    case V4l2PixelFormat::kYuyv: return V4L2_PIX_FMT_YUYV;
    case V4l2PixelFormat::kMjpg: return V4L2_PIX_FMT_MJPEG;
  }
  return 0;
}

/// Bytes per pixel of the uncompressed formats (0: compressed).
std::uint32_t bytesPerPixel(V4l2PixelFormat format) {
  switch (format) {
    case V4l2PixelFormat::kGrey: return 1;
    case V4l2PixelFormat::kYuyv: return 2;
    case V4l2PixelFormat::kMjpg: return 0;
  }
  return 0;
}

std::string upper(std::string_view s) {
  std::string u(s);
  for (char& c : u) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return u;
}

std::string cString(const std::uint8_t* bytes, std::size_t capacity) {
  std::size_t n = 0;
  while (n < capacity && bytes[n] != 0) ++n;
  return std::string(reinterpret_cast<const char*>(bytes), n);
}

}  // namespace

std::optional<V4l2PixelFormat> parseV4l2PixelFormat(std::string_view name) {
  const std::string u = upper(name);
  if (u == "GREY" || u == "GRAY" || u == "Y8") return V4l2PixelFormat::kGrey;
  if (u == "YUYV" || u == "YUY2") return V4l2PixelFormat::kYuyv;
  if (u == "MJPG" || u == "MJPEG" || u == "JPEG") return V4l2PixelFormat::kMjpg;
  return std::nullopt;
}

const char* toString(V4l2PixelFormat format) {
  switch (format) {
    case V4l2PixelFormat::kGrey: return "GREY";
    case V4l2PixelFormat::kYuyv: return "YUYV";
    case V4l2PixelFormat::kMjpg: return "MJPG";
  }
  return "?";
}

std::vector<std::string> validate(const V4l2Options& o) {
  std::vector<std::string> problems;
  if (o.device.empty()) problems.push_back("source.device: must not be empty");
  drivers::appendStreamRequestProblems(problems, o.width, o.height, o.fps);
  if (!parseV4l2PixelFormat(o.format))
    problems.push_back("source.format: '" + o.format +
                       "' is not a V4L2 format this source converts (GREY, YUYV, MJPG)");
  if (o.buffer_count < 2 || o.buffer_count > 32)
    problems.push_back("buffer_count: must be in [2, 32], is " + std::to_string(o.buffer_count));
  drivers::appendClockProblems(problems, o.clock_resync, o.clock_samples);
  if (!(std::abs(o.readout_s) <= SensorTiming::kMaxReadoutS))
    problems.push_back("readout_s: must be finite with |readout_s| <= " +
                       std::to_string(SensorTiming::kMaxReadoutS) +
                       " s (sensor.readout_s of the calibration), is " +
                       std::to_string(o.readout_s));
  return problems;
}

V4l2Source::V4l2Source(Options options, V4l2Io* io)
    : options_(std::move(options)), io_(io != nullptr ? io : &SystemV4l2Io::instance()) {}

V4l2Source::~V4l2Source() { close(); }

// ---------------------------------------------------------------------------------------
// Kernel calls
// ---------------------------------------------------------------------------------------

int V4l2Source::xioctl(unsigned long request, void* arg) {
  for (int attempt = 0;; ++attempt) {
    const int r = io_->ioctl(fd_, request, arg);
    if (r != -1 || errno != EINTR || attempt >= kMaxEintrRetries) return r;
    ++stats_.interrupted;  // a signal interrupted the call: repeat it
  }
}

std::int64_t V4l2Source::nowNs(clockid_t clock) {
  timespec ts{};
  if (io_->clockGettime(clock, &ts) != 0) return -1;
  return drivers::toNanoseconds(ts);
}

void V4l2Source::resyncClock() {
  const drivers::ClockOffset offset = drivers::measureClockOffset(
      [this](clockid_t clock) { return nowNs(clock); }, CLOCK_MONOTONIC, options_.clock_samples);
  if (offset.valid) clock_offset_ = offset;
  last_clock_sync_ns_ = nowNs(CLOCK_MONOTONIC);
}

// ---------------------------------------------------------------------------------------
// Open: negotiate, map, stream
// ---------------------------------------------------------------------------------------

Expected<void> V4l2Source::open() {
  if (state_ != State::kClosed) close();
  if (const auto problems = validate(options_); !problems.empty())
    return fail(ErrorCode::kInvalidArgument, "v4l2 %s: %s", options_.device.c_str(),
                problems.front().c_str());
  auto started = start();
  if (!started) return started;
  state_ = State::kStreaming;
  return {};
}

Expected<void> V4l2Source::start() {
  const char* dev = options_.device.c_str();
  // Non-blocking: DQBUF answers EAGAIN instead of sleeping, poll() does the waiting.
  fd_ = io_->open(dev, O_RDWR | O_NONBLOCK | O_CLOEXEC);
  if (fd_ < 0) {
    const int e = errno;
    fd_ = -1;
    switch (e) {
      case ENOENT:
      case ENOTDIR:
        return fail(ErrorCode::kNotFound, "v4l2 %s: no such device", dev);
      case ENODEV:
      case ENXIO:
        return fail(ErrorCode::kNoDevice, "v4l2 %s: device not present (%s)", dev,
                    std::strerror(e));
      case EBUSY: return fail(ErrorCode::kBusy, "v4l2 %s: device busy", dev);
      case EACCES:
      case EPERM:
        return fail(ErrorCode::kIoError,
                    "v4l2 %s: permission denied (is the user in the 'video' group?)", dev);
      default: return fail(ErrorCode::kIoError, "v4l2 %s: open failed: %s", dev, std::strerror(e));
    }
  }

  auto fail_and_release = [this](Error error) -> Expected<void> {
    teardown();
    return std::unexpected(error);
  };

  // QUERYCAP: is this a V4L2 node, and does *this node* capture video by streaming?
  // device_caps describes the opened node; capabilities the whole device (a UVC camera's
  // metadata node shares the camera's capabilities but not its device_caps).
  v4l2_capability cap{};
  if (xioctl(VIDIOC_QUERYCAP, &cap) != 0) {
    const int e = errno;
    if (e == ENODEV)
      return fail_and_release(Error::format(ErrorCode::kNoDevice, "v4l2 %s: device gone", dev));
    return fail_and_release(Error::format(ErrorCode::kNoDevice,
                                          "v4l2 %s: not a V4L2 device (VIDIOC_QUERYCAP: %s)", dev,
                                          std::strerror(e)));
  }
  const std::uint32_t caps =
      (cap.capabilities & V4L2_CAP_DEVICE_CAPS) != 0 ? cap.device_caps : cap.capabilities;
  if ((caps & V4L2_CAP_VIDEO_CAPTURE) == 0) {
    if ((caps & V4L2_CAP_VIDEO_CAPTURE_MPLANE) != 0)
      return fail_and_release(Error::format(
          ErrorCode::kUnsupportedFormat,
          "v4l2 %s: only offers the multi-planar capture API, which this source does not use",
          dev));
    return fail_and_release(Error::format(
        ErrorCode::kNoDevice,
        "v4l2 %s: not a video capture node (device_caps 0x%08x; a camera's metadata node? "
        "try its other /dev/video*)",
        dev, caps));
  }
  if ((caps & V4L2_CAP_STREAMING) == 0)
    return fail_and_release(Error::format(
        ErrorCode::kUnsupportedFormat, "v4l2 %s: does not support streaming I/O (device_caps 0x%08x)",
        dev, caps));
  negotiated_ = Negotiated{};
  negotiated_.driver = cString(cap.driver, sizeof(cap.driver));
  negotiated_.card = cString(cap.card, sizeof(cap.card));

  if (auto r = negotiateFormat(); !r) return fail_and_release(r.error());
  negotiateFrameRate();
  if (auto r = setUpBuffers(); !r) return fail_and_release(r.error());

  int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(VIDIOC_STREAMON, &type) != 0) {
    const int e = errno;
    return fail_and_release(Error::format(
        e == EBUSY ? ErrorCode::kBusy : e == ENODEV ? ErrorCode::kNoDevice : ErrorCode::kIoError,
        "v4l2 %s: VIDIOC_STREAMON: %s", dev, std::strerror(e)));
  }
  streaming_ = true;
  resyncClock();
  // The driver's counter starts over with the stream (after the caller's close() and
  // open()): ours goes on.
  sequence_.restart();

  std::ostringstream d;
  d << "v4l2 " << options_.device << " " << negotiated_.size.width << "x"
    << negotiated_.size.height << " " << FourccText(negotiated_.fourcc).text;
  if (negotiated_.fps > 0) d << " " << negotiated_.fps << " fps";
  else d << " (frame rate not settable)";
  d << ", " << negotiated_.buffers << " buffers";
  if (negotiated_.size != negotiated_.requested || (negotiated_.fps > 0 &&
      std::abs(negotiated_.fps - negotiated_.requested_fps) > 1e-3 * negotiated_.requested_fps))
    d << " (asked " << negotiated_.requested.width << "x" << negotiated_.requested.height << " @ "
      << negotiated_.requested_fps << " fps)";
  if (!negotiated_.card.empty()) d << " [" << negotiated_.card << "]";
  describe_ = d.str();
  return {};
}

Expected<void> V4l2Source::negotiateFormat() {
  const char* dev = options_.device.c_str();
  const V4l2PixelFormat want = *parseV4l2PixelFormat(options_.format);

  // ENUM_FMT: what does the node offer? (Answers with a clear list instead of relying on
  // S_FMT, which by the specification silently substitutes another format.)
  std::uint32_t offered[kMaxEnumFormats];
  int n_offered = 0;
  for (std::uint32_t i = 0; i < kMaxEnumFormats; ++i) {
    v4l2_fmtdesc desc{};
    desc.index = i;
    desc.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    if (xioctl(VIDIOC_ENUM_FMT, &desc) != 0) {
      if (errno == ENODEV)
        return fail(ErrorCode::kNoDevice, "v4l2 %s: device gone", dev);
      break;  // EINVAL: end of the list
    }
    offered[n_offered++] = desc.pixelformat;
  }
  auto isOffered = [&](std::uint32_t f) {
    return std::find(offered, offered + n_offered, f) != offered + n_offered;
  };
  std::uint32_t fourcc = primaryFourcc(want);
  // Some cameras call their motion JPEG "JPEG"; the bytes are the same.
  if (want == V4l2PixelFormat::kMjpg && !isOffered(fourcc) && isOffered(V4L2_PIX_FMT_JPEG))
    fourcc = V4L2_PIX_FMT_JPEG;
  if (n_offered > 0 && !isOffered(fourcc)) {
    char list[5 * kMaxEnumFormats + 1] = {0};
    for (int i = 0; i < n_offered; ++i) {
      std::strcat(list, i ? " " : "");
      std::strcat(list, FourccText(offered[i]).text);
    }
    return fail(ErrorCode::kUnsupportedFormat, "v4l2 %s: format %s not offered (offers: %s)", dev,
                toString(want), list);
  }

  // S_FMT, then read back what the driver made of it.
  v4l2_format fmt{};
  fmt.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  fmt.fmt.pix.width = static_cast<std::uint32_t>(options_.width);
  fmt.fmt.pix.height = static_cast<std::uint32_t>(options_.height);
  fmt.fmt.pix.pixelformat = fourcc;
  fmt.fmt.pix.field = V4L2_FIELD_NONE;
  if (xioctl(VIDIOC_S_FMT, &fmt) != 0) {
    const int e = errno;
    if (e == EBUSY)
      return fail(ErrorCode::kBusy, "v4l2 %s: busy (streaming in another process?)", dev);
    if (e == ENODEV) return fail(ErrorCode::kNoDevice, "v4l2 %s: device gone", dev);
    if (e == EINVAL)
      return fail(ErrorCode::kUnsupportedFormat, "v4l2 %s: driver rejects %s %dx%d", dev,
                  FourccText(fourcc).text, options_.width, options_.height);
    return fail(ErrorCode::kIoError, "v4l2 %s: VIDIOC_S_FMT: %s", dev, std::strerror(e));
  }
  const v4l2_pix_format& pix = fmt.fmt.pix;
  if (pix.pixelformat != fourcc)
    return fail(ErrorCode::kUnsupportedFormat, "v4l2 %s: driver replaced %s by %s", dev,
                FourccText(fourcc).text, FourccText(pix.pixelformat).text);
  if (pix.field != V4L2_FIELD_NONE && pix.field != V4L2_FIELD_ANY)
    return fail(ErrorCode::kUnsupportedFormat,
                "v4l2 %s: delivers interlaced fields (v4l2_field %u), progressive needed", dev,
                pix.field);
  if (pix.width == 0 || pix.height == 0 || pix.width > limits::kMaxImageSide ||
      pix.height > limits::kMaxImageSide)
    return fail(ErrorCode::kIoError, "v4l2 %s: driver answered a %ux%u format", dev, pix.width,
                pix.height);

  negotiated_.requested = cv::Size(options_.width, options_.height);
  negotiated_.size = cv::Size(static_cast<int>(pix.width), static_cast<int>(pix.height));
  negotiated_.format = want;
  negotiated_.fourcc = fourcc;
  negotiated_.image_bytes = pix.sizeimage;
  const std::uint32_t bpp = bytesPerPixel(want);
  negotiated_.bytes_per_line = pix.bytesperline;
  if (bpp != 0) {
    if (negotiated_.bytes_per_line == 0) negotiated_.bytes_per_line = pix.width * bpp;
    if (negotiated_.bytes_per_line < pix.width * bpp)
      return fail(ErrorCode::kIoError, "v4l2 %s: bytesperline %u < %u for %ux%u %s", dev,
                  pix.bytesperline, pix.width * bpp, pix.width, pix.height,
                  FourccText(fourcc).text);
  }
  return {};
}

void V4l2Source::negotiateFrameRate() {
  negotiated_.requested_fps = options_.fps;
  negotiated_.fps = 0.0;
  v4l2_streamparm parm{};
  parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  if (xioctl(VIDIOC_G_PARM, &parm) != 0) return;  // ENOTTY: no frame-rate control
  if ((parm.parm.capture.capability & V4L2_CAP_TIMEPERFRAME) != 0) {
    // Frame interval as a fraction: 1000 / (fps * 1000) seconds.
    parm = v4l2_streamparm{};
    parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    parm.parm.capture.timeperframe.numerator = 1000;
    parm.parm.capture.timeperframe.denominator =
        static_cast<std::uint32_t>(std::lround(options_.fps * 1000.0));
    if (xioctl(VIDIOC_S_PARM, &parm) != 0) {
      parm = v4l2_streamparm{};
      parm.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      if (xioctl(VIDIOC_G_PARM, &parm) != 0) return;
    }
  }
  const v4l2_fract& t = parm.parm.capture.timeperframe;
  if (t.numerator != 0 && t.denominator != 0)
    negotiated_.fps = static_cast<double>(t.denominator) / static_cast<double>(t.numerator);
}

Expected<void> V4l2Source::setUpBuffers() {
  const char* dev = options_.device.c_str();
  v4l2_requestbuffers req{};
  req.count = static_cast<std::uint32_t>(options_.buffer_count);
  req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  req.memory = V4L2_MEMORY_MMAP;
  if (xioctl(VIDIOC_REQBUFS, &req) != 0) {
    const int e = errno;
    if (e == EBUSY)
      return fail(ErrorCode::kBusy, "v4l2 %s: busy (buffers owned by another process?)", dev);
    if (e == ENODEV) return fail(ErrorCode::kNoDevice, "v4l2 %s: device gone", dev);
    if (e == EINVAL)
      return fail(ErrorCode::kUnsupportedFormat, "v4l2 %s: memory-mapped streaming not supported",
                  dev);
    return fail(ErrorCode::kIoError, "v4l2 %s: VIDIOC_REQBUFS: %s", dev, std::strerror(e));
  }
  buffers_requested_ = true;
  if (req.count < 2)
    return fail(ErrorCode::kIoError, "v4l2 %s: driver granted %u buffer(s), 2 needed", dev,
                req.count);
  negotiated_.buffers = static_cast<int>(req.count);
  buffers_.assign(req.count, Buffer{});
  dequeued_.clear();
  dequeued_.reserve(req.count);

  // QUERYBUF + mmap once per buffer; the mappings live until teardown.
  for (std::uint32_t i = 0; i < req.count; ++i) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    b.index = i;
    if (xioctl(VIDIOC_QUERYBUF, &b) != 0) {
      const int e = errno;
      return fail(e == ENODEV ? ErrorCode::kNoDevice : ErrorCode::kIoError,
                  "v4l2 %s: VIDIOC_QUERYBUF %u: %s", dev, i, std::strerror(e));
    }
    void* p = io_->mmap(nullptr, b.length, PROT_READ | PROT_WRITE, MAP_SHARED, fd_,
                        static_cast<off_t>(b.m.offset));
    if (p == MAP_FAILED) {
      const int e = errno;
      return fail(e == ENODEV ? ErrorCode::kNoDevice : ErrorCode::kIoError,
                  "v4l2 %s: mmap of buffer %u: %s", dev, i, std::strerror(e));
    }
    buffers_[i].data = p;
    buffers_[i].length = b.length;
  }
  // Every frame must fit its buffer.
  const std::uint32_t bpp = bytesPerPixel(negotiated_.format);
  const std::size_t needed =
      bpp == 0 ? 1
               : drivers::minimumFrameBytes(negotiated_.bytes_per_line,
                                            static_cast<std::size_t>(negotiated_.size.width) * bpp,
                                            negotiated_.size.height);
  for (std::uint32_t i = 0; i < req.count; ++i)
    if (buffers_[i].length < needed)
      return fail(ErrorCode::kIoError, "v4l2 %s: buffer %u holds %zu bytes, a frame needs %zu",
                  dev, i, buffers_[i].length, needed);

  queued_count_ = 0;
  for (std::uint32_t i = 0; i < req.count; ++i) {
    if (!requeue(i)) {
      const int e = errno;
      return fail(e == ENODEV ? ErrorCode::kNoDevice : ErrorCode::kIoError,
                  "v4l2 %s: VIDIOC_QBUF %u: %s", dev, i, std::strerror(e));
    }
  }
  return {};
}

void V4l2Source::teardown() {
  if (fd_ < 0) return;
  if (streaming_) {
    int type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    xioctl(VIDIOC_STREAMOFF, &type);  // fails with ENODEV after an unplug: nothing to stop
    streaming_ = false;
  }
  for (Buffer& b : buffers_)
    if (b.data != nullptr) io_->munmap(b.data, b.length);
  buffers_.clear();
  queued_count_ = 0;
  if (buffers_requested_) {
    v4l2_requestbuffers req{};
    req.count = 0;  // free the driver's buffers
    req.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    req.memory = V4L2_MEMORY_MMAP;
    xioctl(VIDIOC_REQBUFS, &req);
    buffers_requested_ = false;
  }
  io_->close(fd_);
  fd_ = -1;
}

void V4l2Source::close() {
  teardown();
  state_ = State::kClosed;
}

std::string V4l2Source::describe() const {
  if (state_ == State::kClosed || describe_.empty())
    return "v4l2 " + options_.device + " " + std::to_string(options_.width) + "x" +
           std::to_string(options_.height) + " " + options_.format + " (not open)";
  if (state_ == State::kDisconnected) return describe_ + " (disconnected)";
  return describe_;
}

// ---------------------------------------------------------------------------------------
// Streaming
// ---------------------------------------------------------------------------------------

bool V4l2Source::requeue(std::uint32_t index) {
  v4l2_buffer b{};
  b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
  b.memory = V4L2_MEMORY_MMAP;
  b.index = index;
  if (xioctl(VIDIOC_QBUF, &b) != 0) return false;
  buffers_[index].queued = true;
  ++queued_count_;
  return true;
}

Error V4l2Source::disconnect(const char* what, int err) {
  teardown();
  state_ = State::kDisconnected;
  ++stats_.disconnects;
  return Error::format(ErrorCode::kDisconnected, "v4l2 %s: device disconnected (%s: %s)",
                       options_.device.c_str(), what, std::strerror(err));
}

Expected<FrameInfo> V4l2Source::next(cv::Mat& out, std::chrono::milliseconds timeout) {
  const char* dev = options_.device.c_str();
  if (state_ == State::kClosed)
    return fail(ErrorCode::kInvalidArgument, "v4l2 %s: next() before open()", dev);
  if (out.type() != CV_8UC1 || out.size() != negotiated_.size)
    return fail(ErrorCode::kInvalidArgument, "v4l2 %s: output must be %dx%d CV_8UC1, is %dx%d",
                dev, negotiated_.size.width, negotiated_.size.height, out.cols, out.rows);
  if (state_ == State::kDisconnected)
    return fail(ErrorCode::kDisconnected, "v4l2 %s: disconnected; close() and open() it again",
                dev);
  const std::int64_t timeout_ns = std::max<std::int64_t>(0, timeout.count()) * kNsPerMs;
  const std::int64_t deadline = nowNs(CLOCK_MONOTONIC) + timeout_ns;
  if (nowNs(CLOCK_MONOTONIC) - last_clock_sync_ns_ >= options_.clock_resync.count() * kNsPerMs)
    resyncClock();

  for (;;) {
    const std::int64_t remaining = deadline - nowNs(CLOCK_MONOTONIC);
    const int wait_ms = remaining <= 0 ? 0
                                       : static_cast<int>(std::min<std::int64_t>(
                                             (remaining + kNsPerMs - 1) / kNsPerMs, 1 << 30));
    pollfd p{fd_, POLLIN, 0};
    const int r = io_->poll(&p, 1, wait_ms);
    if (r < 0) {
      if (errno == EINTR) {
        ++stats_.interrupted;  // a signal: wait again for the rest of the time
        continue;
      }
      return fail(ErrorCode::kIoError, "v4l2 %s: poll: %s", dev, std::strerror(errno));
    }
    if (r == 0)
      return fail(ErrorCode::kTimeout, "v4l2 %s: no frame within %lld ms", dev,
                  static_cast<long long>(timeout.count()));
    if ((p.revents & POLLNVAL) != 0)
      return std::unexpected(disconnect("poll", EBADF));
    if ((p.revents & POLLIN) != 0) {
      FrameInfo info;
      Error error;
      switch (drain(out, info, error)) {
        case Step::kDelivered: return info;
        case Step::kFailed: return std::unexpected(error);
        case Step::kRetry: continue;
      }
    }
    if ((p.revents & (POLLERR | POLLHUP)) != 0) {
      // Unplugged (ENODEV) or the queue failed (EIO): DQBUF says which.
      v4l2_buffer b{};
      b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      b.memory = V4L2_MEMORY_MMAP;
      if (xioctl(VIDIOC_DQBUF, &b) == 0) {
        // A buffer after all (a racing completion): give it back and wait again.
        if (b.index < buffers_.size()) {
          buffers_[b.index].queued = false;
          --queued_count_;
          if (!requeue(b.index)) return std::unexpected(disconnect("VIDIOC_QBUF", errno));
        }
        continue;
      }
      const int e = errno;
      return std::unexpected(disconnect("poll: POLLERR; VIDIOC_DQBUF", e == EAGAIN ? EIO : e));
    }
  }
}

V4l2Source::Step V4l2Source::drain(cv::Mat& out, FrameInfo& info, Error& error) {
  // Dequeue everything that is complete, oldest first.
  dequeued_.clear();
  const int queued_before = queued_count_;
  while (dequeued_.size() < buffers_.size()) {
    v4l2_buffer b{};
    b.type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
    b.memory = V4L2_MEMORY_MMAP;
    if (xioctl(VIDIOC_DQBUF, &b) != 0) {
      const int e = errno;
      if (e == EAGAIN) break;
      // ENODEV: unplugged. EIO / EPIPE / anything else: the stream is broken. Both are
      // handled by reopening.
      error = disconnect("VIDIOC_DQBUF", e);
      return Step::kFailed;
    }
    if (b.index >= buffers_.size() || !buffers_[b.index].queued) {
      error = disconnect("VIDIOC_DQBUF returned a buffer that was not queued", EPROTO);
      return Step::kFailed;
    }
    buffers_[b.index].queued = false;
    --queued_count_;
    // Frames the driver dropped for want of a queued buffer show as sequence gaps.
    stats_.lost_upstream += sequence_.completed(b.sequence);
    Dequeued d;
    d.index = b.index;
    d.sequence = b.sequence;
    d.bytes_used = b.bytesused;
    d.flags = b.flags;
    const bool monotonic =
        (b.flags & V4L2_BUF_FLAG_TIMESTAMP_MASK) == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC;
    d.timestamp_ns = monotonic ? drivers::toNanoseconds(b.timestamp) : 0;
    if (monotonic && (b.flags & V4L2_BUF_FLAG_TSTAMP_SRC_MASK) == V4L2_BUF_FLAG_TSTAMP_SRC_EOF)
      d.timestamp_ns -= static_cast<std::int64_t>(std::llround(std::abs(options_.readout_s) * 1e9));
    dequeued_.push_back(d);
  }
  if (dequeued_.empty()) return Step::kRetry;  // poll raced with nothing: wait again

  // The newest frame without the error flag is delivered, the rest go back. When every
  // queued buffer had completed, the driver ran dry, newer frames were lost and the newest
  // we hold is old: all go back and next() waits for a fresh one.
  const auto plan = drivers::planDrain(
      dequeued_.size(), static_cast<std::size_t>(queued_before), buffers_.size(),
      options_.drop_stale,
      [this](std::size_t i) { return (dequeued_[i].flags & V4L2_BUF_FLAG_ERROR) == 0; });
  const int chosen = plan.deliver;
  int flagged = 0;
  for (int i = 0; i < static_cast<int>(dequeued_.size()); ++i) {
    if (i == chosen) continue;
    const Dequeued& d = dequeued_[static_cast<std::size_t>(i)];
    if ((d.flags & V4L2_BUF_FLAG_ERROR) != 0) {
      ++stats_.error_flagged;
      ++flagged;
    } else {
      ++stats_.stale_dropped;
    }
    if (!requeue(d.index)) {
      error = disconnect("VIDIOC_QBUF", errno);
      return Step::kFailed;
    }
  }
  if (plan.ran_dry) return Step::kRetry;
  if (chosen < 0) {
    error = Error::format(ErrorCode::kBadFrame,
                          "v4l2 %s: %d frame(s) flagged V4L2_BUF_FLAG_ERROR by the driver, dropped",
                          options_.device.c_str(), flagged);
    return Step::kFailed;
  }

  const Dequeued d = dequeued_[static_cast<std::size_t>(chosen)];
  auto converted = convert(d, out);
  const bool requeued = requeue(d.index);
  const int requeue_errno = errno;
  if (!converted) {
    ++stats_.bad_frames;
    error = requeued ? converted.error() : disconnect("VIDIOC_QBUF", requeue_errno);
    return Step::kFailed;
  }

  // Timestamp: the buffer's CLOCK_MONOTONIC time on the wall clock, else the dequeue time.
  info = FrameInfo{};
  info.capture_time_us = drivers::captureTimeUs(d.timestamp_ns, clock_offset_,
                                                [this] { return nowNs(CLOCK_REALTIME); });
  // Sequence: the driver's 32-bit counter, extended to 64 bits; across a close() and
  // open() (the counter restarts) it continues with the gap the frame rate implies.
  info.steady_time_us = (d.timestamp_ns > 0 ? d.timestamp_ns : nowNs(CLOCK_MONOTONIC)) / 1000;
  info.sequence = sequence_.delivered(d.sequence, info.capture_time_us, negotiated_.fps);
  ++stats_.delivered;

  if (!requeued) {
    // The frame is good; the device went away while we had it. Report it next time.
    disconnect("VIDIOC_QBUF", requeue_errno);
  }
  return Step::kDelivered;
}

Expected<void> V4l2Source::convert(const Dequeued& d, cv::Mat& out) {
  const Buffer& buf = buffers_[d.index];
  const auto* src = static_cast<const std::uint8_t*>(buf.data);
  const std::size_t used = std::min<std::size_t>(d.bytes_used, buf.length);
  const std::size_t bpl = negotiated_.bytes_per_line;
  const int w = negotiated_.size.width;
  const int h = negotiated_.size.height;
  switch (negotiated_.format) {
    case V4l2PixelFormat::kGrey: {
      const std::size_t need = drivers::minimumFrameBytes(bpl, static_cast<std::size_t>(w), h);
      if (used < need)
        return fail(ErrorCode::kBadFrame, "v4l2 %s: frame %u has %zu bytes, %zu expected",
                    options_.device.c_str(), d.sequence, used, need);
      drivers::copyLumaPlane(src, bpl, out);
      return {};
    }
    case V4l2PixelFormat::kYuyv: {
      const std::size_t need =
          drivers::minimumFrameBytes(bpl, 2 * static_cast<std::size_t>(w), h);
      if (used < need)
        return fail(ErrorCode::kBadFrame, "v4l2 %s: frame %u has %zu bytes, %zu expected",
                    options_.device.c_str(), d.sequence, used, need);
      drivers::packedYuv422ToGrey(src, bpl, 0, out);
      return {};
    }
    case V4l2PixelFormat::kMjpg: {
      auto r = drivers::decodeJpegToGrey(src, used, jpeg_scratch_, out);
      if (!r)
        return fail(ErrorCode::kBadFrame, "v4l2 %s: frame %u: %s", options_.device.c_str(),
                    d.sequence, r.error().c_str());
      return {};
    }
  }
  return fail(ErrorCode::kUnsupportedFormat, "v4l2: unknown format");
}

}  // namespace omnipose
