// The seam of libcamera_camera.hpp on libcamera itself, and the LibcameraSource
// constructor that uses it.

#include <libcamera/camera.h>
#include <libcamera/camera_manager.h>
#include <libcamera/control_ids.h>
#include <libcamera/controls.h>
#include <libcamera/formats.h>
#include <libcamera/framebuffer.h>
#include <libcamera/framebuffer_allocator.h>
#include <libcamera/request.h>
#include <libcamera/stream.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <mutex>

#include "common/clock_offset.hpp"
#include "libcamera/libcamera_camera.hpp"
#include "libcamera/libcamera_compat.hpp"
#include "libcamera/libcamera_formats.hpp"
#include "libcamera/libcamera_source.hpp"

namespace omnipose {
namespace {

// The fourccs of libcamera_formats.cpp are libcamera's own.
static_assert(libcam::fourcc('R', '8', ' ', ' ') == libcamera::formats::R8.fourcc());
static_assert(libcam::fourcc('N', 'V', '1', '2') == libcamera::formats::NV12.fourcc());
static_assert(libcam::fourcc('Y', 'U', '1', '2') == libcamera::formats::YUV420.fourcc());
static_assert(libcam::fourcc('Y', 'U', 'Y', 'V') == libcamera::formats::YUYV.fourcc());
static_assert(libcam::fourcc('U', 'Y', 'V', 'Y') == libcamera::formats::UYVY.fourcc());
static_assert(libcam::fourcc('M', 'J', 'P', 'G') == libcamera::formats::MJPEG.fourcc());

class RealCamera final : public libcam::Camera {
 public:
  RealCamera(std::shared_ptr<libcamera::CameraManager> manager,
             std::shared_ptr<libcamera::Camera> camera)
      : manager_(std::move(manager)), camera_(std::move(camera)) {
    camera_->requestCompleted.connect(this, &RealCamera::onRequestCompleted);
    camera_->disconnected.connect(this, &RealCamera::onDisconnected);
  }
  ~RealCamera() override {
    camera_->requestCompleted.disconnect(this);
    camera_->disconnected.disconnect(this);
    RealCamera::freeBuffers();
  }

  std::string id() const override { return camera_->id(); }
  int acquire() override { return camera_->acquire(); }
  int release() override { return camera_->release(); }

  bool generateVideoConfiguration(libcam::StreamSettings& settings,
                                  std::vector<std::uint32_t>& offered) override {
    config_ = libcam::generateOneStreamConfiguration(*camera_,
                                                     libcamera::StreamRole::VideoRecording);
    if (!config_ || config_->size() != 1) return false;
    const libcamera::StreamConfiguration& sc = config_->at(0);
    offered.clear();
    for (const libcamera::PixelFormat& pf : sc.formats().pixelformats())
      offered.push_back(pf.fourcc());
    readBack(sc, settings);
    return true;
  }

  libcam::ConfigStatus validate(libcam::StreamSettings& settings) override {
    if (!config_) return libcam::ConfigStatus::kInvalid;
    libcamera::StreamConfiguration& sc = config_->at(0);
    sc.pixelFormat = libcamera::PixelFormat(settings.fourcc);
    sc.size = libcamera::Size(settings.width, settings.height);
    sc.bufferCount = settings.buffer_count;
    const auto status = config_->validate();
    readBack(sc, settings);
    switch (status) {
      case libcamera::CameraConfiguration::Valid: return libcam::ConfigStatus::kValid;
      case libcamera::CameraConfiguration::Adjusted: return libcam::ConfigStatus::kAdjusted;
      case libcamera::CameraConfiguration::Invalid: break;
    }
    return libcam::ConfigStatus::kInvalid;
  }

  int configure() override {
    if (!config_) return -EINVAL;
    const int r = camera_->configure(config_.get());
    if (r == 0) stream_ = config_->at(0).stream();
    return r;
  }

  int allocate(std::vector<std::vector<libcam::BufferPlane>>& buffers) override {
    if (stream_ == nullptr) return -EINVAL;
    allocator_ = std::make_unique<libcamera::FrameBufferAllocator>(camera_);
    if (const int r = allocator_->allocate(stream_); r < 0) return r;
    const auto& allocated = allocator_->buffers(stream_);
    buffers.clear();
    for (std::size_t i = 0; i < allocated.size(); ++i) {
      libcamera::FrameBuffer& buffer = *allocated[i];
      std::vector<libcam::BufferPlane> planes;
      for (const libcamera::FrameBuffer::Plane& p : buffer.planes())
        planes.push_back({p.fd.get(),
                          p.offset == libcamera::FrameBuffer::Plane::kInvalidOffset ? 0u : p.offset,
                          p.length});
      buffers.push_back(std::move(planes));
      std::unique_ptr<libcamera::Request> request = camera_->createRequest(i);
      if (!request) return -ENOMEM;
      if (const int r = request->addBuffer(stream_, &buffer); r < 0) return r;
      requests_.push_back(std::move(request));
    }
    return static_cast<int>(allocated.size());
  }

  bool canSetFrameDuration() const override {
    return camera_->controls().count(&libcamera::controls::FrameDurationLimits) != 0;
  }

  int start(std::int64_t frame_duration_us) override {
    libcamera::ControlList controls(libcamera::controls::controls);
    if (frame_duration_us > 0)
      controls.set(libcamera::controls::FrameDurationLimits,
                   libcamera::Span<const std::int64_t, 2>({frame_duration_us, frame_duration_us}));
    return camera_->start(&controls);
  }

  int queueRequest(std::uint64_t cookie) override {
    if (cookie >= requests_.size()) return -EINVAL;
    libcamera::Request* request = requests_[cookie].get();
    request->reuse(libcamera::Request::ReuseBuffers);
    return camera_->queueRequest(request);
  }

  int stop() override { return camera_->stop(); }

  void freeBuffers() override {
    requests_.clear();
    if (allocator_ && stream_) allocator_->free(stream_);
    allocator_.reset();
    stream_ = nullptr;
  }

  void setListener(libcam::CameraListener* listener) override {
    listener_.store(listener, std::memory_order_release);
  }

 private:
  static void readBack(const libcamera::StreamConfiguration& sc, libcam::StreamSettings& s) {
    s.fourcc = sc.pixelFormat.fourcc();
    s.width = sc.size.width;
    s.height = sc.size.height;
    s.stride = sc.stride;
    s.frame_size = sc.frameSize;
    s.buffer_count = sc.bufferCount;
  }

  // libcamera's thread.
  void onRequestCompleted(libcamera::Request* request) {
    libcam::CameraListener* listener = listener_.load(std::memory_order_acquire);
    if (listener == nullptr) return;
    libcam::Completion c;
    c.cookie = request->cookie();
    c.cancelled = request->status() == libcamera::Request::RequestCancelled;
    if (libcamera::FrameBuffer* b = request->findBuffer(stream_)) {
      const libcamera::FrameMetadata& m = b->metadata();
      c.frame_ok = request->status() == libcamera::Request::RequestComplete &&
                   m.status == libcamera::FrameMetadata::FrameSuccess;
      c.sequence = m.sequence;
      c.timestamp_ns = m.timestamp;
      const auto planes = m.planes();
      c.bytes_used = planes.empty() ? 0 : planes[0].bytesused;
    }
    if (const auto sensor = request->metadata().get(libcamera::controls::SensorTimestamp)) {
      c.has_sensor_timestamp = true;
      c.sensor_timestamp_ns = *sensor;
    }
    if (const auto exposure = request->metadata().get(libcamera::controls::ExposureTime)) {
      c.has_exposure_time = true;
      c.exposure_time_us = *exposure;
    }
    listener->requestCompleted(c);
  }
  void onDisconnected() {
    if (libcam::CameraListener* listener = listener_.load(std::memory_order_acquire))
      listener->disconnected();
  }

  std::shared_ptr<libcamera::CameraManager> manager_;  // outlives the camera
  std::shared_ptr<libcamera::Camera> camera_;
  std::unique_ptr<libcamera::CameraConfiguration> config_;
  libcamera::Stream* stream_ = nullptr;
  std::unique_ptr<libcamera::FrameBufferAllocator> allocator_;
  std::vector<std::unique_ptr<libcamera::Request>> requests_;
  std::atomic<libcam::CameraListener*> listener_{nullptr};
};

class RealCameraManager final : public libcam::CameraManager {
 public:
  explicit RealCameraManager(std::shared_ptr<libcamera::CameraManager> manager)
      : manager_(std::move(manager)) {}

  std::vector<std::shared_ptr<libcam::Camera>> cameras() override {
    std::vector<std::shared_ptr<libcam::Camera>> out;
    for (const auto& c : manager_->cameras()) out.push_back(std::make_shared<RealCamera>(manager_, c));
    return out;
  }
  std::int64_t clockNs(clockid_t clock) override {
    timespec ts{};
    if (::clock_gettime(clock, &ts) != 0) return -1;
    return drivers::toNanoseconds(ts);
  }

 private:
  std::shared_ptr<libcamera::CameraManager> manager_;
};

/// libcamera allows one CameraManager per process: every source shares it, and it stops
/// when the last source lets go.
Expected<std::shared_ptr<libcam::CameraManager>> sharedCameraManager() {
  static std::mutex mutex;
  static std::weak_ptr<libcamera::CameraManager> shared;
  std::lock_guard lock(mutex);
  std::shared_ptr<libcamera::CameraManager> started = shared.lock();
  if (!started) {
    auto manager = std::make_unique<libcamera::CameraManager>();
    if (const int r = manager->start(); r < 0)
      return fail(ErrorCode::kIoError, "libcamera: CameraManager::start failed: %s",
                  std::strerror(-r));
    started = std::shared_ptr<libcamera::CameraManager>(manager.release(),
                                                       [](libcamera::CameraManager* m) {
                                                         m->stop();
                                                         delete m;
                                                       });
    shared = started;
  }
  return std::make_shared<RealCameraManager>(std::move(started));
}

}  // namespace

LibcameraSource::LibcameraSource(Options options)
    : LibcameraSource(std::move(options), &sharedCameraManager) {}

std::string LibcameraSource::libcameraVersion() {
  return std::to_string(LIBCAMERA_VERSION_MAJOR) + "." + std::to_string(LIBCAMERA_VERSION_MINOR) +
         "." + std::to_string(LIBCAMERA_VERSION_PATCH);
}

}  // namespace omnipose
