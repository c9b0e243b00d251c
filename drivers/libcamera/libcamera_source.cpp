#include "libcamera/libcamera_source.hpp"

#include <sys/mman.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <condition_variable>
#include <cstring>
#include <ctime>
#include <limits>
#include <mutex>
#include <sstream>

#include "common/clock_offset.hpp"
#include "common/grey_convert.hpp"
#include "common/streaming.hpp"
#include "libcamera/libcamera_camera.hpp"
#include "libcamera/libcamera_formats.hpp"

namespace omnipose {
namespace {

constexpr std::int64_t kNsPerMs = 1'000'000;
/// Longest wait at teardown for the requests a camera still holds to come back.
constexpr std::chrono::milliseconds kReturnWait{1000};

}  // namespace

// ---------------------------------------------------------------------------------------

struct LibcameraSource::Impl final : libcam::CameraListener {
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

  Impl(Options o, ManagerOpener opener) : options(std::move(o)), open_manager(std::move(opener)) {}

  Options options;
  ManagerOpener open_manager;
  State state = State::kClosed;

  std::shared_ptr<libcam::CameraManager> manager;
  std::shared_ptr<libcam::Camera> camera;
  bool acquired = false;
  bool started = false;
  bool listening = false;
  bool buffers_allocated = false;
  std::vector<Region> regions;  // every mmap, unmapped at teardown
  std::vector<Plane0> planes;   // plane 0 of buffer i (request cookie i)
  int in_flight = 0;            // requests queued to the camera (capture thread)

  const libcam::GreyFormat* format = nullptr;
  cv::Size size;
  std::size_t stride = 0;
  double fps = 0.0;
  std::string camera_id;
  std::string describe_text;

  // Hand-over from libcamera's thread. `completed` has capacity for every request, so the
  // callback never allocates.
  std::mutex mutex;
  std::condition_variable cond;
  std::vector<libcam::Completion> completed;
  bool camera_gone = false;
  std::vector<libcam::Completion> taken;  // capture thread's side of the swap

  drivers::ClockOffset clock_offset;
  std::int64_t last_clock_sync_ns = 0;
  drivers::SequenceTracker sequence;

  cv::Mat jpeg_scratch;
  Stats stats;

  // libcam::CameraListener (libcamera's thread): hand over, nothing else.
  void requestCompleted(const libcam::Completion& completion) override {
    {
      std::lock_guard lock(mutex);
      // Every request completes once per queueing and the capacity is the request count:
      // full means a completion the source never queued for; it is not taken.
      if (completed.size() == completed.capacity()) return;
      completed.push_back(completion);
    }
    cond.notify_one();
  }
  void disconnected() override {
    {
      std::lock_guard lock(mutex);
      camera_gone = true;
    }
    cond.notify_one();
  }

  const char* name() const { return camera_id.empty() ? options.camera.c_str() : camera_id.c_str(); }

  std::int64_t clockNs(clockid_t clock) const { return manager ? manager->clockNs(clock) : -1; }

  void resyncClock() {
    const auto offset = drivers::measureClockOffset(
        [this](clockid_t c) { return clockNs(c); }, CLOCK_BOOTTIME, options.clock_samples);
    if (offset.valid) clock_offset = offset;
    last_clock_sync_ns = clockNs(CLOCK_MONOTONIC);
  }

  Expected<void> start();
  /// The camera named by options.camera, acquired.
  Expected<void> acquireCamera();
  /// One video stream in a grey-convertible format, read back after validate(); true when
  /// the format asked for was not offered and another was taken.
  Expected<bool> configureStream();
  /// describe_text of the running stream.
  void describeStream(bool substituted);
  Expected<void> mapBuffers(const std::vector<std::vector<libcam::BufferPlane>>& buffers);
  void teardown();
  bool requeue(std::uint64_t cookie);
  Error disconnect(const char* why);
  Step take(cv::Mat& out, FrameInfo& info, Error& error);
  Expected<void> convert(const libcam::Completion& completion, cv::Mat& out);
};

Expected<void> LibcameraSource::Impl::acquireCamera() {
  // By index or id.
  const std::vector<std::shared_ptr<libcam::Camera>> cameras = manager->cameras();
  std::vector<std::string> ids;
  for (const auto& c : cameras) ids.push_back(c->id());
  auto index = libcam::selectCamera(libcam::parseCameraSelector(options.camera), ids);
  if (!index)
    return fail(index.error().code(), "libcamera camera %s: %s", options.camera.c_str(),
                index.error().c_str());
  camera = cameras[*index];
  camera_id = ids[*index];
  if (const int r = camera->acquire(); r < 0)
    return fail(r == -EBUSY ? ErrorCode::kBusy : ErrorCode::kIoError,
                "libcamera camera %s: cannot acquire it (%s; in use by another process?)", name(),
                std::strerror(-r));
  acquired = true;
  return {};
}

Expected<bool> LibcameraSource::Impl::configureStream() {
  libcam::StreamSettings sc;
  std::vector<std::uint32_t> offered;
  if (!camera->generateVideoConfiguration(sc, offered))
    return fail(ErrorCode::kUnsupportedFormat, "libcamera camera %s: offers no video stream",
                name());
  auto choice = libcam::chooseFormat(options.format, offered);
  if (!choice)
    return fail(choice.error().code(), "libcamera camera %s: %s", name(), choice.error().c_str());
  sc.fourcc = choice->fourcc;
  sc.width = static_cast<unsigned>(options.width);
  sc.height = static_cast<unsigned>(options.height);
  sc.buffer_count = static_cast<unsigned>(options.buffer_count);
  if (camera->validate(sc) == libcam::ConfigStatus::kInvalid)
    return fail(ErrorCode::kUnsupportedFormat, "libcamera camera %s: rejects %s %dx%d", name(),
                libcam::formatName(choice->fourcc).c_str(), options.width, options.height);
  format = libcam::findGreyFormat(sc.fourcc);
  if (format == nullptr)
    return fail(ErrorCode::kUnsupportedFormat,
                "libcamera camera %s: adjusted the format to %s, which does not convert to grey",
                name(), libcam::formatName(sc.fourcc).c_str());
  size = cv::Size(static_cast<int>(sc.width), static_cast<int>(sc.height));
  stride = sc.stride;
  if (format->conversion != libcam::GreyConversion::kJpeg && stride == 0)
    stride = static_cast<std::size_t>(size.width) *
             (format->conversion == libcam::GreyConversion::kLumaPlane ? 1 : 2);
  return choice->substituted;
}

void LibcameraSource::Impl::describeStream(bool substituted) {
  std::ostringstream d;
  d << "libcamera " << camera_id << " " << size.width << "x" << size.height << " "
    << format->name;
  if (fps > 0) d << " " << fps << " fps";
  else d << " (frame rate not settable)";
  d << ", " << planes.size() << " buffers";
  if (substituted) d << " (" << options.format << " not offered)";
  if (size != cv::Size(options.width, options.height))
    d << " (asked " << options.width << "x" << options.height << ")";
  describe_text = d.str();
}

Expected<void> LibcameraSource::Impl::start() {
  if (!manager) {
    auto m = open_manager();
    if (!m) return std::unexpected(m.error());
    manager = *m;
  }
  if (auto acquired_camera = acquireCamera(); !acquired_camera) return acquired_camera;
  const Expected<bool> substituted = configureStream();
  if (!substituted) return std::unexpected(substituted.error());

  if (const int r = camera->configure(); r < 0)
    return fail(r == -EBUSY ? ErrorCode::kBusy : ErrorCode::kIoError,
                "libcamera camera %s: configure failed: %s", name(), std::strerror(-r));

  std::vector<std::vector<libcam::BufferPlane>> buffers;
  buffers_allocated = true;
  if (const int r = camera->allocate(buffers); r < 0)
    return fail(ErrorCode::kIoError, "libcamera camera %s: buffer allocation failed: %s", name(),
                std::strerror(-r));
  if (auto mapped = mapBuffers(buffers); !mapped) return mapped;

  {
    std::lock_guard lock(mutex);
    completed.clear();
    completed.reserve(planes.size());
    camera_gone = false;
  }
  taken.clear();
  taken.reserve(planes.size());
  camera->setListener(this);
  listening = true;

  // The frame rate, where the camera lets us fix the frame duration.
  fps = 0.0;
  std::int64_t frame_duration_us = 0;
  if (camera->canSetFrameDuration()) {
    frame_duration_us = libcam::frameDurationUs(options.fps);
    fps = 1e6 / static_cast<double>(frame_duration_us);
  }
  if (const int r = camera->start(frame_duration_us); r < 0)
    return fail(ErrorCode::kIoError, "libcamera camera %s: start failed: %s", name(),
                std::strerror(-r));
  started = true;
  in_flight = 0;
  for (std::size_t i = 0; i < planes.size(); ++i)
    if (!requeue(i))
      return fail(ErrorCode::kIoError, "libcamera camera %s: queueing a request failed", name());
  resyncClock();
  // The camera's counter starts over with the stream (after the caller's close() and
  // open()): ours goes on.
  sequence.restart();

  describeStream(*substituted);
  return {};
}

Expected<void> LibcameraSource::Impl::mapBuffers(
    const std::vector<std::vector<libcam::BufferPlane>>& buffers) {
  if (buffers.empty())
    return fail(ErrorCode::kIoError, "libcamera camera %s: no buffers allocated", name());
  const std::size_t bpp = format->conversion == libcam::GreyConversion::kLumaPlane ? 1 : 2;
  const std::size_t needed =
      format->conversion == libcam::GreyConversion::kJpeg
          ? 1
          : drivers::minimumFrameBytes(stride, bpp * static_cast<std::size_t>(size.width),
                                       size.height);
  regions.reserve(buffers.size());
  planes.reserve(buffers.size());
  for (std::size_t i = 0; i < buffers.size(); ++i) {
    const std::vector<libcam::BufferPlane>& buffer_planes = buffers[i];
    if (buffer_planes.empty())
      return fail(ErrorCode::kIoError, "libcamera camera %s: buffer without planes", name());
    // Map plane 0's dmabuf once, far enough to cover every plane that shares it.
    const libcam::BufferPlane& p0 = buffer_planes[0];
    std::size_t extent = 0;
    for (const auto& p : buffer_planes)
      if (p.fd == p0.fd) extent = std::max<std::size_t>(extent, std::size_t{p.offset} + p.length);
    void* addr = ::mmap(nullptr, extent, PROT_READ, MAP_SHARED, p0.fd, 0);
    if (addr == MAP_FAILED)
      return fail(ErrorCode::kIoError, "libcamera camera %s: mmap of buffer %zu: %s", name(), i,
                  std::strerror(errno));
    regions.push_back({addr, extent});
    if (p0.length < needed)
      return fail(ErrorCode::kIoError, "libcamera camera %s: plane of %u bytes, a frame needs %zu",
                  name(), p0.length, needed);
    planes.push_back({static_cast<const std::uint8_t*>(addr) + p0.offset, p0.length});
  }
  return {};
}

void LibcameraSource::Impl::teardown() {
  if (camera && started) camera->stop();  // completes (cancels) every pending request
  started = false;
  if (camera && listening && in_flight > 0) {
    // A disconnected camera is not running, so stop() returns at once, and it completes its
    // pending requests (cancelled) afterwards on libcamera's thread: their buffers are freed
    // below only once every request is back (or after kReturnWait).
    std::unique_lock lock(mutex);
    cond.wait_for(lock, kReturnWait, [this] {
      return completed.size() >= static_cast<std::size_t>(in_flight);
    });
  }
  if (camera && listening) camera->setListener(nullptr);
  listening = false;
  {
    std::lock_guard lock(mutex);
    completed.clear();
    camera_gone = false;
  }
  taken.clear();
  in_flight = 0;
  for (const Region& r : regions) ::munmap(r.addr, r.length);
  regions.clear();
  planes.clear();
  if (camera && buffers_allocated) camera->freeBuffers();
  buffers_allocated = false;
  if (camera && acquired) camera->release();
  acquired = false;
  camera.reset();
}

bool LibcameraSource::Impl::requeue(std::uint64_t cookie) {
  if (camera->queueRequest(cookie) < 0) return false;
  ++in_flight;
  return true;
}

Error LibcameraSource::Impl::disconnect(const char* why) {
  teardown();
  state = State::kDisconnected;
  ++stats.disconnects;
  return Error::format(ErrorCode::kDisconnected, "libcamera camera %s: %s", name(), why);
}

Expected<void> LibcameraSource::Impl::convert(const libcam::Completion& completion,
                                              cv::Mat& out) {
  const Plane0& plane = planes[static_cast<std::size_t>(completion.cookie)];
  const std::size_t used = completion.bytes_used == 0
                               ? plane.length
                               : std::min<std::size_t>(completion.bytes_used, plane.length);
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
  for (const libcam::Completion& c : taken)
    if (!c.cancelled) stats.lost_upstream += sequence.completed(c.sequence);
  auto good = [this](const libcam::Completion& c) {
    return !c.cancelled && c.frame_ok && c.cookie < planes.size();
  };

  // The newest good frame is delivered, the rest go back. When every request had
  // completed, frames after the newest were lost: all go back, wait for a fresh one.
  const auto plan = drivers::planDrain(
      taken.size(), static_cast<std::size_t>(std::max(in_flight_before, 0)), planes.size(),
      options.drop_stale, [&](std::size_t i) { return good(taken[i]); });
  const int chosen = plan.deliver;
  for (int i = 0; i < static_cast<int>(taken.size()); ++i) {
    if (i == chosen) continue;
    const libcam::Completion& c = taken[static_cast<std::size_t>(i)];
    if (good(c)) ++stats.stale_dropped;
    else ++stats.error_frames;
    if (c.cookie >= planes.size()) continue;  // not one of ours
    if (!requeue(c.cookie)) {
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
  const libcam::Completion request = taken[static_cast<std::size_t>(chosen)];
  taken.clear();

  // SensorTimestamp: ns on CLOCK_BOOTTIME; the buffer's own timestamp when absent. Moved to
  // the first row's capture time (the middle of its exposure) as the calibration says.
  const double exposure_s = request.has_exposure_time && request.exposure_time_us > 0
                                ? 1e-6 * request.exposure_time_us
                                : std::numeric_limits<double>::quiet_NaN();
  const double offset_s =
      options.sensor.captureTimeOffset(options.sensor.exposureOf(exposure_s));
  const std::int64_t ts_ns = (request.has_sensor_timestamp
                                  ? request.sensor_timestamp_ns
                                  : static_cast<std::int64_t>(request.timestamp_ns)) +
                             std::llround(offset_s * 1e9);

  auto converted = convert(request, out);
  const bool requeued = requeue(request.cookie);
  if (!converted) {
    ++stats.bad_frames;
    error = requeued ? converted.error() : disconnect("queueing a request failed");
    return Step::kFailed;
  }

  info = FrameInfo{};
  info.capture_time_us = drivers::captureTimeUs(ts_ns, clock_offset,
                                                [this] { return clockNs(CLOCK_REALTIME); });
  // CLOCK_BOOTTIME runs ahead of CLOCK_MONOTONIC by the time the system was suspended.
  const std::int64_t monotonic_now = clockNs(CLOCK_MONOTONIC);
  info.steady_time_us =
      (ts_ns > 0 ? ts_ns - (clockNs(CLOCK_BOOTTIME) - monotonic_now) : monotonic_now) / 1000;
  info.sequence = sequence.delivered(request.sequence, info.capture_time_us, fps);
  info.exposure_s = exposure_s;
  ++stats.delivered;
  if (!requeued) disconnect("queueing a request failed");
  return Step::kDelivered;
}

// ---------------------------------------------------------------------------------------

LibcameraSource::LibcameraSource(Options options, ManagerOpener opener)
    : impl_(std::make_unique<Impl>(std::move(options), std::move(opener))) {}

LibcameraSource::~LibcameraSource() { close(); }

Expected<void> LibcameraSource::open() {
  Impl& d = *impl_;
  if (d.state != Impl::State::kClosed) close();
  if (const auto problems = validate(d.options); !problems.empty())
    return fail(ErrorCode::kInvalidArgument, "libcamera camera %s: %s", d.options.camera.c_str(),
                problems.front().c_str());
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
  if (d.state == Impl::State::kDisconnected)
    return fail(ErrorCode::kDisconnected,
                "libcamera camera %s: disconnected; close() and open() it again", d.name());
  const std::int64_t timeout_ns = std::max<std::int64_t>(0, timeout.count()) * kNsPerMs;
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::nanoseconds(timeout_ns);
  if (d.clockNs(CLOCK_MONOTONIC) - d.last_clock_sync_ns >=
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
      d.in_flight -= static_cast<int>(d.taken.size());  // back, not to be requeued
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
