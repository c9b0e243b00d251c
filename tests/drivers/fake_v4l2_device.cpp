#include "fake_v4l2_device.hpp"

#include <fcntl.h>
#include <sys/mman.h>

#include <algorithm>
#include <cerrno>
#include <climits>
#include <cmath>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

namespace omnipose::testing {
namespace {

constexpr std::uint32_t kPage = 4096;
constexpr std::uint8_t kPadding = 0xEE;   // row padding bytes
constexpr std::uint8_t kScribble = 0xA5;  // what a freshly queued buffer holds

std::uint32_t pageAlign(std::uint32_t n) { return (n + kPage - 1) / kPage * kPage; }

bool isCompressed(std::uint32_t fourcc) {
  return fourcc == V4L2_PIX_FMT_MJPEG || fourcc == V4L2_PIX_FMT_JPEG;
}

std::string fourccText(std::uint32_t f) {
  std::string s(4, ' ');
  for (int i = 0; i < 4; ++i) s[static_cast<std::size_t>(i)] = static_cast<char>((f >> (8 * i)) & 0xFF);
  return s;
}

}  // namespace

FakeV4l2Device::FakeV4l2Device(Config config)
    : config_(std::move(config)), now_ns_(config_.start_monotonic_ns) {
  content_ = &FakeV4l2Device::patternFrame;
  frame_times_.reserve(1 << 16);
  history_.reserve(1 << 16);
  fds_.reserve(16);
  mappings_.reserve(64);
  resetDeviceState();
}

FakeV4l2Device::~FakeV4l2Device() = default;

cv::Mat FakeV4l2Device::patternFrame(std::uint64_t frame, cv::Size size) {
  cv::Mat m(size, CV_8UC1);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x)
      m.at<std::uint8_t>(y, x) =
          static_cast<std::uint8_t>((x * 3 + y * 5 + static_cast<int>(frame) * 37 + (x * y) / 7) & 0xFF);
  return m;
}

void FakeV4l2Device::setContent(Content content) { content_ = std::move(content); }

void FakeV4l2Device::setStalled(bool stalled) {
  if (stalled_ && !stalled) {
    const std::int64_t period =
        1'000'000'000LL * time_per_frame_.numerator / time_per_frame_.denominator;
    next_frame_ns_ = now_ns_ + period;
  }
  stalled_ = stalled;
}

void FakeV4l2Device::injectIoctlError(unsigned long request, int err, int count) {
  injections_.push_back({request, err, count, 0});
}

void FakeV4l2Device::injectPollError(int err, int count, int after_ms) {
  injections_.push_back({0, err, count, after_ms});
}

void FakeV4l2Device::violation(std::string text) { violations_.push_back(std::move(text)); }

int FakeV4l2Device::fail(int err) const {
  errno = err;
  return -1;
}

int FakeV4l2Device::openFdCount() const { return static_cast<int>(fds_.size()); }

FakeV4l2Device::Fd* FakeV4l2Device::findFd(int fd) {
  for (Fd& f : fds_)
    if (f.fd == fd) return &f;
  return nullptr;
}

int FakeV4l2Device::consumeInjection(unsigned long request) {
  for (Injection& in : injections_)
    if (in.request == request && in.remaining > 0) {
      --in.remaining;
      return in.err;
    }
  return 0;
}

void FakeV4l2Device::resetDeviceState() {
  freeBuffers();
  streaming_ = false;
  queue_owner_ = -1;
  content_base_ += sequence_;
  sequence_ = produced_ = lost_ = 0;
  frame_times_.clear();
  time_per_frame_ = v4l2_fract{1, static_cast<std::uint32_t>(config_.frame_rates.front())};
  format_ = v4l2_pix_format{};
  format_.width = 640;
  format_.height = 480;
  format_.pixelformat = config_.formats.front();
  adjustFormat(format_);
}

void FakeV4l2Device::freeBuffers() {
  buffers_.clear();  // storage stays alive while mapped (the kernel orphans it likewise)
  queued_.clear();
  done_.clear();
}

void FakeV4l2Device::adjustFormat(v4l2_pix_format& pix) const {
  if (std::find(config_.formats.begin(), config_.formats.end(), pix.pixelformat) ==
      config_.formats.end())
    pix.pixelformat = config_.formats.front();
  std::uint32_t w = pix.width, h = pix.height;
  if (!config_.discrete_sizes.empty()) {
    // uvcvideo's choice: the frame size with the least area mismatch.
    std::uint64_t best = UINT64_MAX;
    for (const cv::Size& s : config_.discrete_sizes) {
      const std::uint64_t sw = static_cast<std::uint64_t>(s.width), sh = static_cast<std::uint64_t>(s.height);
      const std::uint64_t overlap = std::min<std::uint64_t>(sw, w) * std::min<std::uint64_t>(sh, h);
      const std::uint64_t d = sw * sh + static_cast<std::uint64_t>(w) * h - 2 * overlap;
      if (d < best) {
        best = d;
        pix.width = static_cast<std::uint32_t>(s.width);
        pix.height = static_cast<std::uint32_t>(s.height);
      }
    }
  } else {
    const int step = config_.size_step;
    auto snap = [step](std::uint32_t v, int lo, int hi) {
      long r = std::lround(static_cast<double>(v) / step) * step;
      return static_cast<std::uint32_t>(std::clamp<long>(r, lo, hi));
    };
    pix.width = snap(w, config_.min_size.width, config_.max_size.width);
    pix.height = snap(h, config_.min_size.height, config_.max_size.height);
  }
  pix.field = V4L2_FIELD_NONE;
  const std::uint32_t a = std::max<std::uint32_t>(1, config_.stride_align);
  if (isCompressed(pix.pixelformat)) {
    pix.bytesperline = 0;
    pix.sizeimage = pix.width * pix.height * 2;
    pix.colorspace = V4L2_COLORSPACE_JPEG;
  } else {
    const std::uint32_t bpp = pix.pixelformat == V4L2_PIX_FMT_YUYV ? 2 : 1;
    pix.bytesperline = (pix.width * bpp + a - 1) / a * a;
    pix.sizeimage = pix.bytesperline * pix.height;
    pix.colorspace = V4L2_COLORSPACE_SRGB;
  }
}

// ---------------------------------------------------------------------------------------
// Time and frames
// ---------------------------------------------------------------------------------------

std::int64_t FakeV4l2Device::nextEventNs() const {
  std::int64_t t = INT64_MAX;
  if (unplug_at_ns_ != 0 && plugged_) t = std::min(t, unplug_at_ns_);
  if (replug_at_ns_ != 0 && !plugged_) t = std::min(t, replug_at_ns_);
  if (plugged_ && streaming_ && !stalled_ && content_base_ + sequence_ < stall_after_)
    t = std::min(t, next_frame_ns_);
  return t;
}

void FakeV4l2Device::advanceTo(std::int64_t t_ns) {
  for (;;) {
    const std::int64_t e = nextEventNs();
    if (e > t_ns) break;
    now_ns_ = std::max(now_ns_, e);
    if (plugged_ && unplug_at_ns_ != 0 && e == unplug_at_ns_) {
      unplug_at_ns_ = 0;
      unplug();
    } else if (!plugged_ && replug_at_ns_ != 0 && e == replug_at_ns_) {
      replug_at_ns_ = 0;
      replug();
    } else {
      produceFrame();
    }
  }
  now_ns_ = std::max(now_ns_, t_ns);
}

void FakeV4l2Device::advance(std::int64_t ns) { advanceTo(now_ns_ + ns); }

void FakeV4l2Device::unplug() {
  plugged_ = false;
  ++generation_;  // every open fd now belongs to a device that is gone
  resetDeviceState();
}

void FakeV4l2Device::replug() {
  plugged_ = true;
  resetDeviceState();
}

void FakeV4l2Device::renderContent() {
  encoded_.clear();
  for (int i = 0; i < std::max(1, config_.content_cycle); ++i)
    encoded_.push_back(encode(content_(static_cast<std::uint64_t>(i),
                                       cv::Size(static_cast<int>(format_.width),
                                                static_cast<int>(format_.height)))));
}

std::vector<std::uint8_t> FakeV4l2Device::encode(const cv::Mat& content) const {
  const int w = static_cast<int>(format_.width), h = static_cast<int>(format_.height);
  if (content.cols != w || content.rows != h) {
    const_cast<FakeV4l2Device*>(this)->violation("test content has the wrong size");
    return {};
  }
  if (isCompressed(format_.pixelformat)) {
    std::vector<std::uint8_t> jpeg;
    cv::imencode(".jpg", content, jpeg, {cv::IMWRITE_JPEG_QUALITY, config_.jpeg_quality});
    return jpeg;
  }
  cv::Mat grey = content;
  if (content.channels() == 3) cv::cvtColor(content, grey, cv::COLOR_BGR2GRAY);
  std::vector<std::uint8_t> out(format_.sizeimage, kPadding);
  const std::size_t bpl = format_.bytesperline;
  for (int y = 0; y < h; ++y) {
    std::uint8_t* row = out.data() + static_cast<std::size_t>(y) * bpl;
    const std::uint8_t* g = grey.ptr<std::uint8_t>(y);
    if (format_.pixelformat == V4L2_PIX_FMT_GREY) {
      std::memcpy(row, g, static_cast<std::size_t>(w));
    } else {  // YUYV: Y0 U Y1 V, with chroma that differs from the luma
      for (int x = 0; x < w; ++x) {
        row[2 * x] = g[x];
        const int pair = x / 2;
        row[2 * x + 1] = static_cast<std::uint8_t>((x % 2 == 0) ? (pair * 17 + y * 3) & 0xFF
                                                                 : 255 - ((pair * 11 + y) & 0xFF));
      }
    }
  }
  return out;
}

void FakeV4l2Device::produceFrame() {
  const std::uint64_t k = sequence_++;
  const std::int64_t t = next_frame_ns_;
  next_frame_ns_ += 1'000'000'000LL * time_per_frame_.numerator / time_per_frame_.denominator;
  const std::int64_t t_us = t / 1000 * 1000;  // a timeval holds microseconds
  frame_times_.push_back(t_us);
  history_.push_back({t_us, content_base_ + k});
  if (queued_.empty()) {
    ++lost_;  // no buffer to capture into: the frame is gone, the counter moved on
    return;
  }
  Buffer& b = buffers_[queued_.pop()];
  const std::vector<std::uint8_t>& bytes = encoded_[(content_base_ + k) % encoded_.size()];
  std::size_t n = bytes.size();
  if (n > b.length) {
    violation("frame larger than its buffer (test setup)");
    n = b.length;
  }
  std::memcpy(b.storage.get(), bytes.data(), n);
  b.bytes_used = static_cast<std::uint32_t>(n);
  b.flags = config_.timestamp_type;
  if (config_.timestamp_type == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC)
    b.flags |= config_.timestamp_source;
  for (std::uint64_t s : error_frames_)
    if (s == k) b.flags |= V4L2_BUF_FLAG_ERROR;
  for (const auto& [s, bytes_left] : truncated_frames_)
    if (s == k) b.bytes_used = std::min(b.bytes_used, bytes_left);
  for (std::uint64_t s : corrupt_frames_)
    if (s == k) std::memset(b.storage.get(), 0x5A, std::min<std::size_t>(n, 4096));
  b.sequence = static_cast<std::uint32_t>(k);
  if (config_.timestamp_type == V4L2_BUF_FLAG_TIMESTAMP_MONOTONIC) {
    b.timestamp.tv_sec = t_us / 1'000'000'000;
    b.timestamp.tv_usec = (t_us % 1'000'000'000) / 1000;
  } else {
    b.timestamp = timeval{};
  }
  b.state = BufState::kDone;
  done_.push(static_cast<std::uint32_t>(&b - buffers_.data()));
  ++produced_;
}

std::int64_t FakeV4l2Device::frameTimestampNs(std::uint64_t sequence) const {
  return sequence < frame_times_.size() ? frame_times_[sequence] : -1;
}

std::int64_t FakeV4l2Device::contentIndexAt(std::int64_t timestamp_ns) const {
  for (const auto& [t, content] : history_)
    if (t == timestamp_ns) return static_cast<std::int64_t>(content);
  return -1;
}

cv::Mat FakeV4l2Device::expectedGrey(std::uint64_t sequence) const {
  const std::uint64_t cycle = static_cast<std::uint64_t>(std::max(1, config_.content_cycle));
  cv::Mat c = content_((content_base_ + sequence) % cycle, cv::Size(static_cast<int>(format_.width),
                                                  static_cast<int>(format_.height)));
  if (c.channels() == 3) cv::cvtColor(c, c, cv::COLOR_BGR2GRAY);
  return c;
}

// ---------------------------------------------------------------------------------------
// V4l2Io
// ---------------------------------------------------------------------------------------

int FakeV4l2Device::open(const char* path, int flags) {
  open_attempts_.push_back(now_ns_);
  advanceTo(now_ns_);
  if (!plugged_ && replug_after_failed_opens_ == 0) {
    replug_after_failed_opens_ = -1;
    replug();
  }
  if (path == nullptr || config_.path != path || !plugged_) {
    if (!plugged_ && replug_after_failed_opens_ > 0) --replug_after_failed_opens_;
    return fail(ENOENT);
  }
  Fd f;
  f.fd = next_fd_++;
  f.generation = generation_;
  f.nonblocking = (flags & O_NONBLOCK) != 0;
  fds_.push_back(f);
  return f.fd;
}

int FakeV4l2Device::close(int fd) {
  auto it = std::find_if(fds_.begin(), fds_.end(), [fd](const Fd& f) { return f.fd == fd; });
  if (it == fds_.end()) {
    violation("close() of fd " + std::to_string(fd) + " that is not open");
    return fail(EBADF);
  }
  if (alive(*it) && queue_owner_ == fd) {
    // Releasing the owning file handle stops streaming and frees the queue.
    streaming_ = false;
    freeBuffers();
    queue_owner_ = -1;
  }
  fds_.erase(it);
  return 0;
}

int FakeV4l2Device::ioctl(int fd, unsigned long request, void* arg) {
  Fd* f = findFd(fd);
  if (f == nullptr) {
    violation("ioctl on fd " + std::to_string(fd) + " that is not open");
    return fail(EBADF);
  }
  if (!alive(*f)) return fail(ENODEV);
  if (arg == nullptr) return fail(EFAULT);
  if (const int err = consumeInjection(request); err != 0) return fail(err);
  return doIoctl(*f, request, arg);
}

int FakeV4l2Device::doIoctl(Fd& f, unsigned long request, void* arg) {
  switch (request) {
    case VIDIOC_QUERYCAP: {
      auto* cap = static_cast<v4l2_capability*>(arg);
      *cap = v4l2_capability{};
      std::snprintf(reinterpret_cast<char*>(cap->driver), sizeof(cap->driver), "uvcvideo");
      std::snprintf(reinterpret_cast<char*>(cap->card), sizeof(cap->card), "%s", config_.card.c_str());
      std::snprintf(reinterpret_cast<char*>(cap->bus_info), sizeof(cap->bus_info), "usb-fake-1");
      cap->version = (6u << 16) | (1u << 8);
      // capabilities: the whole device (video + metadata node); device_caps: this node.
      cap->capabilities = V4L2_CAP_VIDEO_CAPTURE | V4L2_CAP_META_CAPTURE | V4L2_CAP_STREAMING |
                          V4L2_CAP_DEVICE_CAPS;
      cap->device_caps = config_.device_caps;
      return 0;
    }
    case VIDIOC_ENUM_FMT: {
      auto* d = static_cast<v4l2_fmtdesc*>(arg);
      if (d->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      if ((config_.device_caps & V4L2_CAP_VIDEO_CAPTURE) == 0) return fail(EINVAL);
      if (d->index >= config_.formats.size()) return fail(EINVAL);
      const std::uint32_t index = d->index;
      *d = v4l2_fmtdesc{};
      d->index = index;
      d->type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      d->pixelformat = config_.formats[index];
      d->flags = isCompressed(d->pixelformat) ? V4L2_FMT_FLAG_COMPRESSED : 0;
      std::snprintf(reinterpret_cast<char*>(d->description), sizeof(d->description), "%s",
                    fourccText(d->pixelformat).c_str());
      return 0;
    }
    case VIDIOC_G_FMT:
    case VIDIOC_TRY_FMT:
    case VIDIOC_S_FMT: {
      auto* fmt = static_cast<v4l2_format*>(arg);
      if (fmt->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      if ((config_.device_caps & V4L2_CAP_VIDEO_CAPTURE) == 0) return fail(EINVAL);
      if (request == VIDIOC_G_FMT) {
        fmt->fmt.pix = format_;
        return 0;
      }
      if (request == VIDIOC_S_FMT) {
        if (busy_) return fail(EBUSY);
        if (streaming_ || !buffers_.empty()) return fail(EBUSY);  // vb2_is_busy()
      }
      v4l2_pix_format pix = fmt->fmt.pix;
      const bool offered = std::find(config_.formats.begin(), config_.formats.end(),
                                     pix.pixelformat) != config_.formats.end();
      if (!offered && config_.unsupported_format == UnsupportedFormatPolicy::kEinval)
        return fail(EINVAL);
      adjustFormat(pix);
      fmt->fmt.pix = pix;
      if (request == VIDIOC_S_FMT) format_ = pix;
      return 0;
    }
    case VIDIOC_G_PARM:
    case VIDIOC_S_PARM: {
      if (!config_.frame_rate_settable) return fail(ENOTTY);
      auto* parm = static_cast<v4l2_streamparm*>(arg);
      if (parm->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      if (request == VIDIOC_S_PARM) {
        if (streaming_) return fail(EBUSY);  // uvcvideo refuses while streaming
        const v4l2_fract req = parm->parm.capture.timeperframe;
        int fps = config_.frame_rates.front();
        if (req.numerator != 0 && req.denominator != 0) {
          const double want = static_cast<double>(req.numerator) / req.denominator;  // seconds
          double best = 1e300;
          for (int r : config_.frame_rates)
            if (std::abs(1.0 / r - want) < best) {
              best = std::abs(1.0 / r - want);
              fps = r;
            }
        }
        time_per_frame_ = v4l2_fract{1, static_cast<std::uint32_t>(fps)};
      }
      *parm = v4l2_streamparm{};
      parm->type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      parm->parm.capture.capability = V4L2_CAP_TIMEPERFRAME;
      parm->parm.capture.timeperframe = time_per_frame_;
      parm->parm.capture.readbuffers = 0;
      return 0;
    }
    case VIDIOC_REQBUFS: {
      auto* rb = static_cast<v4l2_requestbuffers*>(arg);
      if (rb->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      if (rb->memory != V4L2_MEMORY_MMAP) return fail(EINVAL);
      if (busy_) return fail(EBUSY);
      if (queue_owner_ != -1 && queue_owner_ != f.fd) return fail(EBUSY);
      if (streaming_) return fail(EBUSY);
      freeBuffers();
      if (rb->count == 0) {
        queue_owner_ = -1;
        rb->capabilities = V4L2_BUF_CAP_SUPPORTS_MMAP;
        return 0;
      }
      const std::uint32_t n = std::clamp(rb->count, config_.min_buffers, config_.max_buffers);
      const std::uint32_t length = format_.sizeimage;
      buffers_.resize(n);
      for (std::uint32_t i = 0; i < n; ++i) {
        Buffer& b = buffers_[i];
        b.storage = std::shared_ptr<std::uint8_t[]>(new std::uint8_t[pageAlign(length)]);
        std::memset(b.storage.get(), kScribble, pageAlign(length));
        b.length = length;
        b.offset = i * pageAlign(length);
        b.state = BufState::kDequeued;
      }
      queue_owner_ = f.fd;
      rb->count = n;
      rb->capabilities = V4L2_BUF_CAP_SUPPORTS_MMAP;
      return 0;
    }
    case VIDIOC_QUERYBUF: {
      auto* b = static_cast<v4l2_buffer*>(arg);
      if (b->type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      if (b->index >= buffers_.size()) return fail(EINVAL);
      const std::uint32_t index = b->index;
      const Buffer& buf = buffers_[index];
      *b = v4l2_buffer{};
      b->index = index;
      b->type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      b->memory = V4L2_MEMORY_MMAP;
      b->length = buf.length;
      b->m.offset = buf.offset;
      b->bytesused = buf.bytes_used;
      b->flags = config_.timestamp_type;
      for (const Mapping& m : mappings_)
        if (m.storage == buf.storage) b->flags |= V4L2_BUF_FLAG_MAPPED;
      if (buf.state == BufState::kQueued) b->flags |= V4L2_BUF_FLAG_QUEUED;
      if (buf.state == BufState::kDone) b->flags |= V4L2_BUF_FLAG_DONE;
      return 0;
    }
    case VIDIOC_QBUF: {
      auto* b = static_cast<v4l2_buffer*>(arg);
      if (b->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || b->memory != V4L2_MEMORY_MMAP)
        return fail(EINVAL);
      if (queue_owner_ != f.fd) return fail(EBUSY);
      if (b->index >= buffers_.size()) {
        violation("QBUF of index " + std::to_string(b->index) + " beyond the " +
                  std::to_string(buffers_.size()) + " buffers");
        return fail(EINVAL);
      }
      Buffer& buf = buffers_[b->index];
      if (buf.state != BufState::kDequeued) {
        violation("QBUF of buffer " + std::to_string(b->index) + " that is not dequeued");
        return fail(EINVAL);
      }
      // The driver owns it again: its old content is gone.
      std::memset(buf.storage.get(), kScribble, buf.length);
      buf.state = BufState::kQueued;
      buf.bytes_used = 0;
      queued_.push(b->index);
      b->flags = (b->flags & ~V4L2_BUF_FLAG_DONE) | V4L2_BUF_FLAG_QUEUED;
      return 0;
    }
    case VIDIOC_DQBUF: {
      auto* b = static_cast<v4l2_buffer*>(arg);
      if (b->type != V4L2_BUF_TYPE_VIDEO_CAPTURE || b->memory != V4L2_MEMORY_MMAP)
        return fail(EINVAL);
      if (queue_owner_ != f.fd) return fail(EBUSY);
      if (!streaming_) return fail(EINVAL);
      advanceTo(now_ns_);
      if (done_.empty()) {
        if (!f.nonblocking) violation("blocking DQBUF with nothing done would sleep forever");
        return fail(EAGAIN);
      }
      const std::uint32_t index = done_.pop();
      Buffer& buf = buffers_[index];
      *b = v4l2_buffer{};
      b->index = index;
      b->type = V4L2_BUF_TYPE_VIDEO_CAPTURE;
      b->memory = V4L2_MEMORY_MMAP;
      b->bytesused = buf.bytes_used;
      b->flags = buf.flags | V4L2_BUF_FLAG_DONE | V4L2_BUF_FLAG_MAPPED;
      b->field = V4L2_FIELD_NONE;
      b->timestamp = buf.timestamp;
      b->sequence = buf.sequence;
      b->length = buf.length;
      b->m.offset = buf.offset;
      buf.state = BufState::kDequeued;
      return 0;
    }
    case VIDIOC_STREAMON: {
      const int type = *static_cast<int*>(arg);
      if (type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      if (queue_owner_ != f.fd || buffers_.empty()) return fail(EINVAL);
      if (streaming_) return 0;
      streaming_ = true;
      ++streamon_count_;
      content_base_ += sequence_;
      sequence_ = produced_ = lost_ = 0;
      frame_times_.clear();
      renderContent();
      next_frame_ns_ =
          now_ns_ + 1'000'000'000LL * time_per_frame_.numerator / time_per_frame_.denominator;
      return 0;
    }
    case VIDIOC_STREAMOFF: {
      const int type = *static_cast<int*>(arg);
      if (type != V4L2_BUF_TYPE_VIDEO_CAPTURE) return fail(EINVAL);
      if (queue_owner_ != -1 && queue_owner_ != f.fd) return fail(EBUSY);
      streaming_ = false;
      for (Buffer& b : buffers_) b.state = BufState::kDequeued;  // all back to the user
      queued_.clear();
      done_.clear();
      return 0;
    }
    default: return fail(ENOTTY);
  }
}

short FakeV4l2Device::readiness(const Fd& f) const {
  if (!alive(f)) return POLLERR | POLLHUP | POLLPRI;
  if (f.fd != queue_owner_ || !streaming_) return POLLERR;  // vb2: not streaming
  if (!done_.empty()) return POLLIN | POLLRDNORM;
  return 0;
}

int FakeV4l2Device::poll(pollfd* fds, nfds_t nfds, int timeout_ms) {
  ++poll_calls_;
  if (timeout_ms < 0) {
    violation("poll() without a timeout");
    timeout_ms = 60'000;
  }
  const std::int64_t deadline = now_ns_ + static_cast<std::int64_t>(timeout_ms) * 1'000'000;
  if (nfds == 0) {  // a sleep
    advanceTo(deadline);
    return 0;
  }
  if (nfds != 1) violation("poll() of more than one descriptor");
  for (Injection& in : injections_)
    if (in.request == 0 && in.remaining > 0) {
      --in.remaining;
      advanceTo(std::min<std::int64_t>(deadline, now_ns_ + in.after_ms * 1'000'000LL));
      return fail(in.err);
    }
  fds[0].revents = 0;
  for (;;) {
    Fd* f = findFd(fds[0].fd);
    const short ready = f == nullptr ? POLLNVAL : readiness(*f);
    const short revents =
        static_cast<short>(ready & (fds[0].events | POLLERR | POLLHUP | POLLNVAL));
    if (revents != 0) {
      fds[0].revents = revents;
      return 1;
    }
    const std::int64_t e = nextEventNs();
    if (e > deadline) {
      advanceTo(deadline);
      f = findFd(fds[0].fd);
      const short late = f == nullptr ? POLLNVAL : readiness(*f);
      fds[0].revents = static_cast<short>(late & (fds[0].events | POLLERR | POLLHUP | POLLNVAL));
      return fds[0].revents != 0 ? 1 : 0;
    }
    advanceTo(e);
  }
}

void* FakeV4l2Device::mmap(void* /*addr*/, std::size_t length, int prot, int flags, int fd,
                           off_t offset) {
  Fd* f = findFd(fd);
  if (f == nullptr) {
    violation("mmap on fd that is not open");
    errno = EBADF;
    return MAP_FAILED;
  }
  if (!alive(*f)) {
    errno = ENODEV;
    return MAP_FAILED;
  }
  if ((flags & MAP_SHARED) == 0 || (prot & PROT_READ) == 0) {
    violation("mmap of a V4L2 buffer needs MAP_SHARED and PROT_READ");
    errno = EINVAL;
    return MAP_FAILED;
  }
  for (const Buffer& b : buffers_) {
    if (static_cast<off_t>(b.offset) != offset) continue;
    if (length == 0 || length > pageAlign(b.length)) {
      violation("mmap length " + std::to_string(length) + " does not match buffer length " +
                std::to_string(b.length));
      errno = EINVAL;
      return MAP_FAILED;
    }
    mappings_.push_back({b.storage.get(), length, b.storage});
    return b.storage.get();
  }
  violation("mmap offset " + std::to_string(offset) + " is no buffer's QUERYBUF offset");
  errno = EINVAL;
  return MAP_FAILED;
}

int FakeV4l2Device::munmap(void* addr, std::size_t length) {
  for (auto it = mappings_.begin(); it != mappings_.end(); ++it)
    if (it->addr == addr && it->length == length) {
      mappings_.erase(it);
      return 0;
    }
  violation("munmap of something that was not mapped (or with another length)");
  return fail(EINVAL);
}

int FakeV4l2Device::clockGettime(clockid_t clock, timespec* ts) {
  std::int64_t value = 0;
  switch (clock) {
    case CLOCK_MONOTONIC:
    case CLOCK_MONOTONIC_RAW:
    case CLOCK_BOOTTIME: value = now_ns_; break;
    case CLOCK_REALTIME:
      ++realtime_reads_;
      if (realtime_delay_every_ > 0 &&
          realtime_reads_ % static_cast<std::uint64_t>(realtime_delay_every_) == 0)
        advanceTo(now_ns_ + realtime_delay_ns_);  // preempted just before this read
      value = now_ns_ + config_.realtime_offset_ns;
      break;
    default: return fail(EINVAL);
  }
  ts->tv_sec = value / 1'000'000'000;
  ts->tv_nsec = value % 1'000'000'000;
  advanceTo(now_ns_ + config_.clock_read_cost_ns);
  return 0;
}

}  // namespace omnipose::testing
