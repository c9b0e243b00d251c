#include "libcamera/libcamera_source.hpp"

#include <libcamera/camera.h>
#include <libcamera/camera_manager.h>
#include <libcamera/control_ids.h>
#include <libcamera/controls.h>
#include <libcamera/formats.h>
#include <libcamera/framebuffer.h>
#include <libcamera/framebuffer_allocator.h>
#include <libcamera/request.h>
#include <libcamera/stream.h>
#include <sys/mman.h>

#include <algorithm>
#include <cerrno>
#include <condition_variable>
#include <cstring>
#include <ctime>
#include <mutex>
#include <sstream>
#include <thread>

#include "common/clock_offset.hpp"
#include "common/grey_convert.hpp"
#include "common/streaming.hpp"
#include "libcamera/libcamera_compat.hpp"
#include "libcamera/libcamera_formats.hpp"

namespace omnipose {
namespace {

// The fourccs of libcamera_formats.cpp are libcamera's own.
static_assert(libcam::fourcc('R', '8', ' ', ' ') == libcamera::formats::R8.fourcc());
static_assert(libcam::fourcc('N', 'V', '1', '2') == libcamera::formats::NV12.fourcc());
static_assert(libcam::fourcc('Y', 'U', '1', '2') == libcamera::formats::YUV420.fourcc());
static_assert(libcam::fourcc('Y', 'U', 'Y', 'V') == libcamera::formats::YUYV.fourcc());
static_assert(libcam::fourcc('U', 'Y', 'V', 'Y') == libcamera::formats::UYVY.fourcc());
static_assert(libcam::fourcc('M', 'J', 'P', 'G') == libcamera::formats::MJPEG.fourcc());

constexpr std::int64_t kNsPerMs = 1'000'000;

std::int64_t readClockNs(clockid_t clock) {
  timespec ts{};
  if (::clock_gettime(clock, &ts) != 0) return -1;
  return drivers::toNanoseconds(ts);
}

/// libcamera allows one CameraManager per process: every source shares it, and it stops
/// when the last source lets go.
Expected<std::shared_ptr<libcamera::CameraManager>> sharedCameraManager() {
  static std::mutex mutex;
  static std::weak_ptr<libcamera::CameraManager> shared;
  std::lock_guard lock(mutex);
  if (auto existing = shared.lock()) return existing;
  auto manager = std::make_unique<libcamera::CameraManager>();
  if (const int r = manager->start(); r < 0)
    return fail(ErrorCode::kIoError, "libcamera: CameraManager::start failed: %s",
                std::strerror(-r));
  std::shared_ptr<libcamera::CameraManager> started(manager.release(),
                                                    [](libcamera::CameraManager* m) {
                                                      m->stop();
                                                      delete m;
                                                    });
  shared = started;
  return started;
}

}  // namespace

// ---------------------------------------------------------------------------------------

struct LibcameraSource::Impl {
  enum class State { kClosed, kStreaming, kDisconnected };
  enum class Step { kDelivered, kRetry, kFailed };
  struct Region {
    void* addr = nullptr;
    std::size_t length = 0;
  };
  struct Plane0 {
    const std::uint8_t* data = nullptr;
    std::size_t length = 0;
  };

  explicit Impl(Options o)
      : options(std::move(o)), reconnect(options.reconnect_initial, options.reconnect_max) {}

  Options options;
  State state = State::kClosed;

  std::shared_ptr<libcamera::CameraManager> manager;
  std::shared_ptr<libcamera::Camera> camera;
  bool acquired = false;
  bool started = false;
  bool signals_connected = false;
  std::unique_ptr<libcamera::CameraConfiguration> camera_config;
  libcamera::Stream* stream = nullptr;
  std::unique_ptr<libcamera::FrameBufferAllocator> allocator;
  std::vector<std::unique_ptr<libcamera::Request>> requests;
  std::vector<Region> regions;  // every mmap, unmapped at teardown
  std::vector<Plane0> planes;   // plane 0 of buffer i (cookie i)
  int in_flight = 0;            // requests queued to the camera (capture thread)

  const libcam::GreyFormat* format = nullptr;
  cv::Size size;
  std::optional<cv::Size> first_size;  // what a reopen must reproduce
  std::size_t stride = 0;
  double fps = 0.0;
  std::string camera_id;
  std::string describe_text;

  // Hand-over from libcamera's thread. `completed` has capacity for every request, so the
  // callback never allocates.
  std::mutex mutex;
  std::condition_variable cond;
  std::vector<libcamera::Request*> completed;
  bool camera_gone = false;
  std::vector<libcamera::Request*> taken;  // capture thread's side of the swap

  drivers::ClockOffset clock_offset;
  std::int64_t last_clock_sync_ns = 0;
  drivers::ReconnectSchedule reconnect;
  drivers::SequenceTracker sequence;

  cv::Mat jpeg_scratch;
  Stats stats;

  // Callbacks (libcamera's thread): hand over, nothing else.
  void onRequestCompleted(libcamera::Request* request) {
    {
      std::lock_guard lock(mutex);
      completed.push_back(request);
    }
    cond.notify_one();
  }
  void onDisconnected() {
    {
      std::lock_guard lock(mutex);
      camera_gone = true;
    }
    cond.notify_one();
  }

  const char* name() const { return camera_id.empty() ? options.camera.c_str() : camera_id.c_str(); }

  void resyncClock() {
    const auto offset =
        drivers::measureClockOffset(readClockNs, CLOCK_BOOTTIME, options.clock_samples);
    if (offset.valid) clock_offset = offset;
    last_clock_sync_ns = readClockNs(CLOCK_MONOTONIC);
  }

  Expected<void> start();
  Expected<void> mapBuffers();
  void teardown();
  bool requeue(libcamera::Request* request);
  Error disconnect(const char* why);
  Expected<void> recover(std::int64_t deadline_ns);
  Step take(cv::Mat& out, FrameInfo& info, Error& error);
  Expected<void> convert(const libcamera::FrameBuffer& buffer, cv::Mat& out);
};

Expected<void> LibcameraSource::Impl::start() {
  auto m = sharedCameraManager();
  if (!m) return std::unexpected(m.error());
  manager = *m;

  // The camera, by index or id.
  const std::vector<std::shared_ptr<libcamera::Camera>> cameras = manager->cameras();
  std::vector<std::string> ids;
  for (const auto& c : cameras) ids.push_back(c->id());
  auto index = libcam::selectCamera(libcam::parseCameraSelector(options.camera), ids);
  if (!index)
    return fail(index.error().code(), "libcamera camera %s: %s", options.camera.c_str(),
                index.error().c_str());
  camera = cameras[*index];
  camera_id = camera->id();
  if (const int r = camera->acquire(); r < 0)
    return fail(r == -EBUSY ? ErrorCode::kBusy : ErrorCode::kIoError,
                "libcamera camera %s: cannot acquire it (%s; in use by another process?)", name(),
                std::strerror(-r));
  acquired = true;

  // One video stream in a grey-convertible format, read back after validate().
  camera_config =
      libcam::generateOneStreamConfiguration(*camera, libcamera::StreamRole::VideoRecording);
  if (!camera_config || camera_config->size() != 1)
    return fail(ErrorCode::kUnsupportedFormat, "libcamera camera %s: offers no video stream",
                name());
  libcamera::StreamConfiguration& sc = camera_config->at(0);
  std::vector<std::uint32_t> offered;
  for (const libcamera::PixelFormat& pf : sc.formats().pixelformats())
    offered.push_back(pf.fourcc());
  auto choice = libcam::chooseFormat(options.format, offered);
  if (!choice)
    return fail(choice.error().code(), "libcamera camera %s: %s", name(), choice.error().c_str());
  sc.pixelFormat = libcamera::PixelFormat(choice->fourcc);
  sc.size = libcamera::Size(static_cast<unsigned>(options.width),
                            static_cast<unsigned>(options.height));
  sc.bufferCount = static_cast<unsigned>(options.buffer_count);
  if (camera_config->validate() == libcamera::CameraConfiguration::Invalid)
    return fail(ErrorCode::kUnsupportedFormat, "libcamera camera %s: rejects %s %dx%d", name(),
                libcam::formatName(choice->fourcc).c_str(), options.width, options.height);
  format = libcam::findGreyFormat(sc.pixelFormat.fourcc());
  if (format == nullptr)
    return fail(ErrorCode::kUnsupportedFormat,
                "libcamera camera %s: adjusted the format to %s, which does not convert to grey",
                name(), sc.pixelFormat.toString().c_str());
  size = cv::Size(static_cast<int>(sc.size.width), static_cast<int>(sc.size.height));
  stride = sc.stride;
  if (format->conversion != libcam::GreyConversion::kJpeg && stride == 0)
    stride = static_cast<std::size_t>(size.width) *
             (format->conversion == libcam::GreyConversion::kLumaPlane ? 1 : 2);
  if (first_size && *first_size != size)
    return fail(ErrorCode::kUnsupportedFormat, "libcamera camera %s: came back as %dx%d, was %dx%d",
                name(), size.width, size.height, first_size->width, first_size->height);

  if (const int r = camera->configure(camera_config.get()); r < 0)
    return fail(r == -EBUSY ? ErrorCode::kBusy : ErrorCode::kIoError,
                "libcamera camera %s: configure failed: %s", name(), std::strerror(-r));
  stream = sc.stream();

  allocator = std::make_unique<libcamera::FrameBufferAllocator>(camera);
  if (const int r = allocator->allocate(stream); r < 0)
    return fail(ErrorCode::kIoError, "libcamera camera %s: buffer allocation failed: %s", name(),
                std::strerror(-r));
  if (auto mapped = mapBuffers(); !mapped) return mapped;

  completed.clear();
  completed.reserve(requests.size());
  taken.clear();
  taken.reserve(requests.size());
  camera_gone = false;
  camera->requestCompleted.connect(this, &Impl::onRequestCompleted);
  camera->disconnected.connect(this, &Impl::onDisconnected);
  signals_connected = true;

  // The frame rate, where the camera lets us fix the frame duration.
  libcamera::ControlList controls(libcamera::controls::controls);
  fps = 0.0;
  if (camera->controls().count(&libcamera::controls::FrameDurationLimits) != 0) {
    const std::int64_t d = libcam::frameDurationUs(options.fps);
    controls.set(libcamera::controls::FrameDurationLimits,
                 libcamera::Span<const std::int64_t, 2>({d, d}));
    fps = 1e6 / static_cast<double>(d);
  }
  if (const int r = camera->start(&controls); r < 0)
    return fail(ErrorCode::kIoError, "libcamera camera %s: start failed: %s", name(),
                std::strerror(-r));
  started = true;
  in_flight = 0;
  for (auto& request : requests)
    if (!requeue(request.get()))
      return fail(ErrorCode::kIoError, "libcamera camera %s: queueing a request failed", name());
  resyncClock();
  // The camera's counter starts over with the stream (after a reconnect, or the caller's
  // close() and open()): ours goes on.
  sequence.restart();
  if (!first_size) first_size = size;

  std::ostringstream d;
  d << "libcamera " << camera_id << " " << size.width << "x" << size.height << " "
    << format->name;
  if (fps > 0) d << " " << fps << " fps";
  else d << " (frame rate not settable)";
  d << ", " << requests.size() << " buffers";
  if (choice->substituted) d << " (" << options.format << " not offered)";
  if (size != cv::Size(options.width, options.height))
    d << " (asked " << options.width << "x" << options.height << ")";
  describe_text = d.str();
  return {};
}

Expected<void> LibcameraSource::Impl::mapBuffers() {
  const auto& buffers = allocator->buffers(stream);
  if (buffers.empty())
    return fail(ErrorCode::kIoError, "libcamera camera %s: no buffers allocated", name());
  const std::size_t bpp = format->conversion == libcam::GreyConversion::kLumaPlane ? 1 : 2;
  const std::size_t needed =
      format->conversion == libcam::GreyConversion::kJpeg
          ? 1
          : drivers::minimumFrameBytes(stride, bpp * static_cast<std::size_t>(size.width),
                                       size.height);
  for (std::size_t i = 0; i < buffers.size(); ++i) {
    libcamera::FrameBuffer& buffer = *buffers[i];
    buffer.setCookie(i);
    const auto& buffer_planes = buffer.planes();
    if (buffer_planes.empty())
      return fail(ErrorCode::kIoError, "libcamera camera %s: buffer without planes", name());
    // Map plane 0's dmabuf once, far enough to cover every plane that shares it.
    const libcamera::FrameBuffer::Plane& p0 = buffer_planes[0];
    const int fd = p0.fd.get();
    auto offsetOf = [](const libcamera::FrameBuffer::Plane& p) -> std::size_t {
      return p.offset == libcamera::FrameBuffer::Plane::kInvalidOffset ? 0 : p.offset;
    };
    std::size_t extent = 0;
    for (const auto& p : buffer_planes)
      if (p.fd.get() == fd) extent = std::max(extent, offsetOf(p) + p.length);
    void* addr = ::mmap(nullptr, extent, PROT_READ, MAP_SHARED, fd, 0);
    if (addr == MAP_FAILED)
      return fail(ErrorCode::kIoError, "libcamera camera %s: mmap of buffer %zu: %s", name(), i,
                  std::strerror(errno));
    regions.push_back({addr, extent});
    if (p0.length < needed)
      return fail(ErrorCode::kIoError, "libcamera camera %s: plane of %u bytes, a frame needs %zu",
                  name(), p0.length, needed);
    planes.push_back({static_cast<const std::uint8_t*>(addr) + offsetOf(p0), p0.length});

    std::unique_ptr<libcamera::Request> request = camera->createRequest(i);
    if (!request)
      return fail(ErrorCode::kIoError, "libcamera camera %s: createRequest failed", name());
    if (const int r = request->addBuffer(stream, &buffer); r < 0)
      return fail(ErrorCode::kIoError, "libcamera camera %s: addBuffer: %s", name(),
                  std::strerror(-r));
    requests.push_back(std::move(request));
  }
  return {};
}

void LibcameraSource::Impl::teardown() {
  if (camera && started) camera->stop();  // completes (cancels) every pending request
  started = false;
  if (camera && signals_connected) {
    camera->requestCompleted.disconnect(this);
    camera->disconnected.disconnect(this);
  }
  signals_connected = false;
  {
    std::lock_guard lock(mutex);
    completed.clear();
    camera_gone = false;
  }
  taken.clear();
  requests.clear();
  in_flight = 0;
  for (const Region& r : regions) ::munmap(r.addr, r.length);
  regions.clear();
  planes.clear();
  if (allocator && stream) allocator->free(stream);
  allocator.reset();
  stream = nullptr;
  camera_config.reset();
  if (camera && acquired) camera->release();
  acquired = false;
  camera.reset();
}

bool LibcameraSource::Impl::requeue(libcamera::Request* request) {
  request->reuse(libcamera::Request::ReuseBuffers);
  if (camera->queueRequest(request) < 0) return false;
  ++in_flight;
  return true;
}

Error LibcameraSource::Impl::disconnect(const char* why) {
  teardown();
  state = State::kDisconnected;
  ++stats.disconnects;
  reconnect.lost(readClockNs(CLOCK_MONOTONIC));
  return Error::format(ErrorCode::kDisconnected,
                       "libcamera camera %s: %s; reopening with back-off", name(), why);
}

Expected<void> LibcameraSource::Impl::recover(std::int64_t deadline_ns) {
  using Action = drivers::ReconnectSchedule::Action;
  for (;;) {
    const auto step = reconnect.step(readClockNs(CLOCK_MONOTONIC), deadline_ns);
    if (step.action == Action::kAttempt) break;
    if (step.sleep_ns > 0) std::this_thread::sleep_for(std::chrono::nanoseconds(step.sleep_ns));
    if (step.action == Action::kGiveBack)
      return fail(ErrorCode::kDisconnected, "libcamera camera %s: disconnected; reopening later",
                  name());
  }
  auto started_again = start();
  if (started_again) {
    state = State::kStreaming;
    ++stats.reconnects;
    reconnect.reconnected();
    return {};
  }
  teardown();
  ++stats.reopen_failures;
  const std::int64_t delay = reconnect.attemptFailed(readClockNs(CLOCK_MONOTONIC));
  return fail(ErrorCode::kDisconnected,
              "libcamera camera %s: still disconnected (%s); next attempt in %lld ms", name(),
              started_again.error().c_str(), static_cast<long long>(delay));
}

Expected<void> LibcameraSource::Impl::convert(const libcamera::FrameBuffer& buffer,
                                              cv::Mat& out) {
  const std::size_t index = static_cast<std::size_t>(buffer.cookie());
  if (index >= planes.size())
    return fail(ErrorCode::kBadFrame, "libcamera camera %s: unknown buffer", name());
  const Plane0& plane = planes[index];
  const auto meta_planes = buffer.metadata().planes();
  const std::size_t used =
      meta_planes.empty() ? plane.length : std::min<std::size_t>(meta_planes[0].bytesused, plane.length);
  switch (format->conversion) {
    case libcam::GreyConversion::kLumaPlane:
      drivers::copyLumaPlane(plane.data, stride, out);
      return {};
    case libcam::GreyConversion::kPackedLuma0:
      drivers::packedYuv422ToGrey(plane.data, stride, 0, out);
      return {};
    case libcam::GreyConversion::kPackedLuma1:
      drivers::packedYuv422ToGrey(plane.data, stride, 1, out);
      return {};
    case libcam::GreyConversion::kJpeg: {
      auto r = drivers::decodeJpegToGrey(plane.data, used, jpeg_scratch, out);
      if (!r)
        return fail(ErrorCode::kBadFrame, "libcamera camera %s: %s", name(), r.error().c_str());
      return {};
    }
  }
  return fail(ErrorCode::kUnsupportedFormat, "libcamera: unknown conversion");
}

LibcameraSource::Impl::Step LibcameraSource::Impl::take(cv::Mat& out, FrameInfo& info,
                                                         Error& error) {
  // taken: completed requests, oldest first (the callback appends in completion order).
  const int in_flight_before = in_flight;
  in_flight -= static_cast<int>(taken.size());
  for (libcamera::Request* r : taken) {
    libcamera::FrameBuffer* b = r->findBuffer(stream);
    if (b == nullptr) continue;
    stats.lost_upstream += sequence.completed(b->metadata().sequence);
  }
  auto good = [this](libcamera::Request* r) {
    libcamera::FrameBuffer* b = r->findBuffer(stream);
    return r->status() == libcamera::Request::RequestComplete && b != nullptr &&
           b->metadata().status == libcamera::FrameMetadata::FrameSuccess;
  };

  // The newest good frame is delivered, the rest go back. When every request had
  // completed, frames after the newest were lost: all go back, wait for a fresh one.
  const auto plan = drivers::planDrain(
      taken.size(), static_cast<std::size_t>(std::max(in_flight_before, 0)), requests.size(),
      options.drop_stale, [&](std::size_t i) { return good(taken[i]); });
  const int chosen = plan.deliver;
  for (int i = 0; i < static_cast<int>(taken.size()); ++i) {
    if (i == chosen) continue;
    libcamera::Request* r = taken[static_cast<std::size_t>(i)];
    if (good(r)) ++stats.stale_dropped;
    else ++stats.error_frames;
    if (!requeue(r)) {
      error = disconnect("queueing a request failed");
      return Step::kFailed;
    }
  }
  if (plan.ran_dry) {
    taken.clear();
    return Step::kRetry;
  }
  if (chosen < 0) {
    error = Error::format(ErrorCode::kBadFrame,
                          "libcamera camera %s: %zu frame(s) completed with an error, dropped",
                          name(), taken.size());
    taken.clear();
    return Step::kFailed;
  }
  libcamera::Request* request = taken[static_cast<std::size_t>(chosen)];
  taken.clear();
  const libcamera::FrameBuffer& buffer = *request->findBuffer(stream);
  const std::uint32_t buffer_seq = buffer.metadata().sequence;

  // SensorTimestamp: ns on CLOCK_BOOTTIME; the buffer's own timestamp when absent.
  std::int64_t ts_ns = static_cast<std::int64_t>(buffer.metadata().timestamp);
  if (const auto sensor = request->metadata().get(libcamera::controls::SensorTimestamp))
    ts_ns = *sensor;

  auto converted = convert(buffer, out);
  const bool requeued = requeue(request);
  if (!converted) {
    ++stats.bad_frames;
    error = requeued ? converted.error() : disconnect("queueing a request failed");
    return Step::kFailed;
  }

  info = FrameInfo{};
  info.capture_time_us = drivers::captureTimeUs(ts_ns, clock_offset,
                                                [] { return readClockNs(CLOCK_REALTIME); });
  info.sequence = sequence.delivered(buffer_seq, info.capture_time_us, fps);
  ++stats.delivered;
  if (!requeued) disconnect("queueing a request failed");
  return Step::kDelivered;
}

// ---------------------------------------------------------------------------------------

LibcameraSource::LibcameraSource(Options options)
    : impl_(std::make_unique<Impl>(std::move(options))) {}

LibcameraSource::~LibcameraSource() { close(); }

std::string LibcameraSource::libcameraVersion() {
  return std::to_string(LIBCAMERA_VERSION_MAJOR) + "." + std::to_string(LIBCAMERA_VERSION_MINOR) +
         "." + std::to_string(LIBCAMERA_VERSION_PATCH);
}

Expected<void> LibcameraSource::open() {
  Impl& d = *impl_;
  if (d.state != Impl::State::kClosed) close();
  if (const auto problems = validate(d.options); !problems.empty())
    return fail(ErrorCode::kInvalidArgument, "libcamera camera %s: %s", d.options.camera.c_str(),
                problems.front().c_str());
  d.first_size.reset();
  auto started = d.start();
  if (!started) {
    d.teardown();
    d.manager.reset();
    return started;
  }
  d.state = Impl::State::kStreaming;
  return {};
}

cv::Size LibcameraSource::frameSize() const { return impl_->size; }

const LibcameraSource::Stats& LibcameraSource::stats() const { return impl_->stats; }

Expected<FrameInfo> LibcameraSource::next(cv::Mat& out, std::chrono::milliseconds timeout) {
  Impl& d = *impl_;
  if (d.state == Impl::State::kClosed)
    return fail(ErrorCode::kInvalidArgument, "libcamera camera %s: next() before open()",
                d.options.camera.c_str());
  if (out.type() != CV_8UC1 || out.size() != d.size)
    return fail(ErrorCode::kInvalidArgument,
                "libcamera camera %s: output must be %dx%d CV_8UC1, is %dx%d", d.name(),
                d.size.width, d.size.height, out.cols, out.rows);
  const std::int64_t timeout_ns = std::max<std::int64_t>(0, timeout.count()) * kNsPerMs;
  const std::int64_t deadline_ns = readClockNs(CLOCK_MONOTONIC) + timeout_ns;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::nanoseconds(timeout_ns);
  if (d.state == Impl::State::kDisconnected) {
    if (auto r = d.recover(deadline_ns); !r) return std::unexpected(r.error());
  }
  if (readClockNs(CLOCK_MONOTONIC) - d.last_clock_sync_ns >=
      d.options.clock_resync.count() * kNsPerMs)
    d.resyncClock();

  for (;;) {
    bool gone = false;
    {
      std::unique_lock lock(d.mutex);
      d.cond.wait_until(lock, deadline, [&d] { return !d.completed.empty() || d.camera_gone; });
      gone = d.camera_gone;
      d.taken.clear();
      std::swap(d.taken, d.completed);  // both reserved: no allocation
    }
    if (gone) {
      d.taken.clear();
      return std::unexpected(d.disconnect("camera disconnected"));
    }
    if (d.taken.empty())
      return fail(ErrorCode::kTimeout, "libcamera camera %s: no frame within %lld ms", d.name(),
                  static_cast<long long>(timeout.count()));
    FrameInfo info;
    Error error;
    switch (d.take(out, info, error)) {
      case Impl::Step::kDelivered: return info;
      case Impl::Step::kFailed: return std::unexpected(error);
      case Impl::Step::kRetry: continue;
    }
  }
}

void LibcameraSource::close() {
  Impl& d = *impl_;
  d.teardown();
  d.manager.reset();
  d.state = Impl::State::kClosed;
}

std::string LibcameraSource::describe() const {
  const Impl& d = *impl_;
  if (d.state == Impl::State::kClosed || d.describe_text.empty())
    return "libcamera camera " + d.options.camera + " " + std::to_string(d.options.width) + "x" +
           std::to_string(d.options.height) + " " + d.options.format + " (not open)";
  if (d.state == Impl::State::kDisconnected) return d.describe_text + " (disconnected)";
  return d.describe_text;
}

}  // namespace omnipose
