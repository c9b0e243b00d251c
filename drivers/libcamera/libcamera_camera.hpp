#pragma once
/// \file libcamera_camera.hpp
/// The seam between LibcameraSource and libcamera: the part of libcamera's API the source
/// uses, in plain types, with no libcamera header. libcamera_real.cpp adapts libcamera
/// itself (the robot); tests/drivers/fake_libcamera.* is a fake that behaves as libcamera
/// 0.0.3 does.
///
///   libcamera                                 here
///   CameraManager::cameras()                  CameraManager::cameras()
///   Camera::acquire() / release()             Camera::acquire() / release()
///   generateConfiguration({VideoRecording})   Camera::generateVideoConfiguration()
///   CameraConfiguration::validate()           Camera::validate() (kValid/kAdjusted/kInvalid)
///   Camera::configure()                       Camera::configure()
///   FrameBufferAllocator::allocate() and one  Camera::allocate(): the buffers' planes; the
///   createRequest(i) + addBuffer() per buffer   request of buffer i has cookie i
///   Camera::start(FrameDurationLimits)        Camera::start()
///   Request::reuse(ReuseBuffers) + queue      Camera::queueRequest(cookie)
///   Camera::stop()                            Camera::stop()
///   Camera::requestCompleted                  CameraListener::requestCompleted(Completion)
///   Camera::disconnected                      CameraListener::disconnected()
///   controls::SensorTimestamp (metadata)      Completion::sensor_timestamp_ns
///   controls::ExposureTime (metadata)         Completion::exposure_time_us
///
/// Cost on the robot: one virtual call per completed request (the listener) and one per
/// queued request; the adapter copies a request's result into a Completion on libcamera's
/// thread (no allocation).
///
/// The clocks (CLOCK_BOOTTIME, CLOCK_REALTIME, CLOCK_MONOTONIC) go through CameraManager
/// too, so a fake can run them on virtual time.

#include <ctime>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace omnipose::libcam {

/// The StreamConfiguration fields the source sets and reads back.
struct StreamSettings {
  std::uint32_t fourcc = 0;    ///< PixelFormat::fourcc()
  unsigned width = 0;          ///< size.width, pixels
  unsigned height = 0;         ///< size.height, pixels
  unsigned stride = 0;         ///< bytes per row of plane 0 (0: not reported)
  unsigned frame_size = 0;     ///< bytes of a frame (0: not reported)
  unsigned buffer_count = 0;   ///< bufferCount
};

/// CameraConfiguration::Status.
enum class ConfigStatus { kValid, kAdjusted, kInvalid };

/// FrameBuffer::Plane: a dmabuf (or memfd) with the plane at `offset`.
struct BufferPlane {
  int fd = -1;
  unsigned offset = 0;  ///< resolved: libcamera's kInvalidOffset is given as 0
  unsigned length = 0;
};

/// A completed request, copied on the camera's thread when libcamera completes it.
struct Completion {
  std::uint64_t cookie = 0;             ///< Request::cookie(): the buffer index
  bool cancelled = false;               ///< Request::status() == RequestCancelled
  bool frame_ok = false;                ///< FrameMetadata::status == FrameSuccess
  std::uint32_t sequence = 0;           ///< FrameMetadata::sequence
  std::uint64_t timestamp_ns = 0;       ///< FrameMetadata::timestamp
  std::uint32_t bytes_used = 0;         ///< FrameMetadata::planes()[0].bytesused
  bool has_sensor_timestamp = false;    ///< the request's metadata has SensorTimestamp
  std::int64_t sensor_timestamp_ns = 0; ///< controls::SensorTimestamp (CLOCK_BOOTTIME, ns)
  bool has_exposure_time = false;       ///< the request's metadata has ExposureTime
  std::int32_t exposure_time_us = 0;    ///< controls::ExposureTime, microseconds
};

/// The source's side of libcamera's signals. Called on libcamera's (or the fake's) thread.
class CameraListener {
 public:
  virtual void requestCompleted(const Completion& completion) = 0;
  virtual void disconnected() = 0;

 protected:
  ~CameraListener() = default;
};

/// One camera. Return values are libcamera's: 0 or a negative errno (-ENODEV once the
/// camera is disconnected, -EBUSY when acquired elsewhere, -EACCES in the wrong state).
class Camera {
 public:
  virtual ~Camera() = default;
  virtual std::string id() const = 0;
  virtual int acquire() = 0;
  virtual int release() = 0;
  /// A one-stream VideoRecording configuration: its defaults in `settings` and the pixel
  /// formats the stream offers in `offered`. false: the camera offers no such stream.
  virtual bool generateVideoConfiguration(StreamSettings& settings,
                                          std::vector<std::uint32_t>& offered) = 0;
  /// Sets the generated configuration to `settings` and validates it; `settings` is read
  /// back (adjusted, stride and frame size filled in).
  virtual ConfigStatus validate(StreamSettings& settings) = 0;
  /// Configures the camera with the last validated configuration.
  virtual int configure() = 0;
  /// Allocates the stream's buffers and one request per buffer (cookie = index); `buffers`
  /// gets each buffer's planes. Returns the count or a negative errno.
  virtual int allocate(std::vector<std::vector<BufferPlane>>& buffers) = 0;
  /// Whether controls::FrameDurationLimits is among the camera's controls.
  virtual bool canSetFrameDuration() const = 0;
  /// Starts; frame_duration_us > 0 sets FrameDurationLimits to {d, d}.
  virtual int start(std::int64_t frame_duration_us) = 0;
  /// Reuses (ReuseBuffers) and queues the request of `cookie`.
  virtual int queueRequest(std::uint64_t cookie) = 0;
  /// Stops: every pending request completes, cancelled, before it returns.
  virtual int stop() = 0;
  /// Frees the requests and buffers of allocate().
  virtual void freeBuffers() = 0;
  /// Where requestCompleted / disconnected go; nullptr: nowhere.
  virtual void setListener(CameraListener* listener) = 0;
};

/// The process's camera manager (libcamera allows one, started) and the clocks.
class CameraManager {
 public:
  virtual ~CameraManager() = default;
  /// The cameras present now, in libcamera's order.
  virtual std::vector<std::shared_ptr<Camera>> cameras() = 0;
  /// clock_gettime(clock) in nanoseconds; negative when the read failed.
  virtual std::int64_t clockNs(clockid_t clock) = 0;
};

}  // namespace omnipose::libcam
