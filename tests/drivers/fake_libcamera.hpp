#pragma once
/// \file fake_libcamera.hpp
/// A libcamera in user space, behind the seam of drivers/libcamera/libcamera_camera.hpp,
/// that behaves as libcamera 0.0.3 does (its camera.cpp state machine, the UVC and
/// Raspberry Pi pipelines' configuration rules), strictly enough that a source passing
/// against it would work on a camera:
///
/// - Camera states Available -> Acquired -> Configured -> Running. acquire() gives -EBUSY
///   when acquired (here or by "another process", setBusy()); configure() needs Acquired or
///   Configured and a configuration that validates as Valid (-EINVAL otherwise); allocate()
///   needs Configured; start() needs Configured; queueRequest() needs Running (-EACCES);
///   stop() when not running is a no-op returning 0; release() while running gives -EBUSY.
///   Once disconnected every call but release(), stop() and freeBuffers() gives -ENODEV.
/// - validate(): a pixel format not offered becomes the first offered, the size the nearest
///   supported one (sum of |dw| + |dh|), the buffer count is clamped: kAdjusted; settings
///   unchanged: kValid; rejectConfigurations(): kInvalid. The stride is the row rounded up
///   to stride_align (wider than the width), frame_size is what a frame occupies.
/// - allocate(): one memfd per buffer (as a dmabuf: the source maps it); NV12's two planes
///   share it (UV at offset stride * height), as on a Raspberry Pi.
/// - Requests complete on the manager's own thread (libcamera's), in queueing order, one per
///   sensor frame; a frame with no request queued is lost (the sequence still advances). A
///   queued buffer is scribbled over, so reading it after requeueing shows up as wrong
///   pixels. stop() completes every pending request as cancelled before it returns.
/// - Unplug (unplug()): the camera leaves cameras(), emits disconnected, stops running
///   (Configured) and completes its pending requests as cancelled afterwards ("disconnected
///   cameras are still able to complete requests"). replug() adds a new camera object under
///   the same id.
/// - Clocks are virtual: CLOCK_MONOTONIC advances with frames, sleeps and a little per read;
///   CLOCK_BOOTTIME = monotonic + suspended time; CLOCK_REALTIME = boottime + an offset.
///   SensorTimestamp is the boottime of the frame (or absent: config).
///
/// Everything a source does wrong is recorded in violations(); tests assert it stays empty.
/// No libcamera header is needed.

#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <mutex>
#include <opencv2/core.hpp>
#include <string>
#include <thread>
#include <vector>

#include "libcamera/libcamera_camera.hpp"
#include "libcamera/libcamera_formats.hpp"

namespace omnipose::testing {

inline constexpr std::uint32_t kFakeR8 = libcam::fourcc('R', '8', ' ', ' ');
inline constexpr std::uint32_t kFakeNV12 = libcam::fourcc('N', 'V', '1', '2');
inline constexpr std::uint32_t kFakeYUYV = libcam::fourcc('Y', 'U', 'Y', 'V');
inline constexpr std::uint32_t kFakeXRGB = libcam::fourcc('X', 'R', '2', '4');

struct FakeCameraConfig {
  std::string id = "/base/soc/i2c0mux/i2c@1/imx708@1a";
  /// Offered pixel formats, in StreamFormats order (R8, NV12, YUYV, XR24 supported).
  std::vector<std::uint32_t> formats = {kFakeXRGB, kFakeNV12, kFakeYUYV};
  /// Supported sizes; validate() picks the nearest.
  std::vector<cv::Size> sizes = {{320, 240}, {640, 480}, {1280, 720}};
  /// Row stride alignment in bytes.
  unsigned stride_align = 64;
  unsigned min_buffers = 1;
  unsigned max_buffers = 8;
  bool frame_duration_settable = true;
  bool sensor_timestamp = true;
  /// ExposureTime in each request's metadata, microseconds: frame n (the camera's sequence)
  /// reports exposure_time_us[n % size]; empty: none reported.
  std::vector<std::int32_t> exposure_time_us;
  std::int64_t default_frame_duration_ns = 33'333'333;
};

class FakeCameraManager;

class FakeCamera final : public libcam::Camera {
 public:
  FakeCamera(FakeCameraManager& manager, FakeCameraConfig config);
  ~FakeCamera() override;

  // ---- libcam::Camera ---------------------------------------------------------------
  std::string id() const override { return config_.id; }
  int acquire() override;
  int release() override;
  bool generateVideoConfiguration(libcam::StreamSettings& settings,
                                  std::vector<std::uint32_t>& offered) override;
  libcam::ConfigStatus validate(libcam::StreamSettings& settings) override;
  int configure() override;
  int allocate(std::vector<std::vector<libcam::BufferPlane>>& buffers) override;
  bool canSetFrameDuration() const override { return config_.frame_duration_settable; }
  int start(std::int64_t frame_duration_us) override;
  int queueRequest(std::uint64_t cookie) override;
  int stop() override;
  void freeBuffers() override;
  void setListener(libcam::CameraListener* listener) override;

  // ---- inspection -------------------------------------------------------------------
  bool running() const;
  bool acquired() const;
  bool disconnectedFlag() const;
  int pendingRequests() const;
  int allocatedBuffers() const;
  /// The configuration of the last validate() (the one configure() applies).
  libcam::StreamSettings configured() const;
  std::int64_t frameDurationUs() const;
  int startCount() const;

 private:
  friend class FakeCameraManager;
  enum class State { kAvailable, kAcquired, kConfigured, kRunning };
  struct Buffer {
    int fd = -1;
    std::uint8_t* map = nullptr;
    std::size_t size = 0;
  };
  // Pipeline thread.
  void produceFrame(std::uint64_t content_index, bool flag_error);
  void cancelPending();
  void disconnectNow();
  void deliver(const libcam::Completion& completion);
  int access(bool allow_disconnected) const;  // -ENODEV or 0; m_ held

  FakeCameraManager& manager_;
  const FakeCameraConfig config_;
  mutable std::mutex m_;
  State state_ = State::kAvailable;
  bool disconnected_ = false;
  libcam::StreamSettings validated_{};
  bool have_validated_ = false;
  std::vector<Buffer> buffers_;
  std::uint64_t ring_[64] = {};  // pending request cookies, FIFO
  int ring_head_ = 0, ring_count_ = 0;
  std::vector<bool> queued_;
  std::int64_t frame_duration_us_ = 0;
  std::uint32_t sequence_ = 0;
  int start_count_ = 0;
  std::mutex listener_mutex_;
  libcam::CameraListener* listener_ = nullptr;
};

class FakeCameraManager final : public libcam::CameraManager,
                                public std::enable_shared_from_this<FakeCameraManager> {
 public:
  FakeCameraManager();
  ~FakeCameraManager() override;

  /// What LibcameraSource's second constructor takes.
  static std::function<Expected<std::shared_ptr<libcam::CameraManager>>()> opener(
      std::shared_ptr<FakeCameraManager> manager);

  // ---- scripting (test thread) --------------------------------------------------------
  /// A camera appears (libcamera's cameraAdded); returns it.
  std::shared_ptr<FakeCamera> plug(FakeCameraConfig config = {});
  /// The camera of `id` goes away mid-stream (see the file comment); waits until done.
  void unplug(const std::string& id);
  /// An unplugged camera cancels its pending requests `delay` after its disconnected signal
  /// (default 0: right after it), as a slow pipeline handler would.
  void setCancelDelayAfterDisconnect(std::chrono::microseconds delay);
  /// The camera of `id` comes back as a new object with its last config.
  std::shared_ptr<FakeCamera> replug(const std::string& id);
  /// ... when the virtual CLOCK_MONOTONIC reaches `at_ns` (checked on clock reads/sleeps).
  void scheduleReplug(const std::string& id, std::int64_t at_ns);
  /// The camera of `id`, or nullptr when unplugged.
  std::shared_ptr<FakeCamera> camera(const std::string& id) const;
  /// Another process holds every camera: acquire() gives -EBUSY.
  void setBusy(bool busy);
  /// Every configuration validates as Invalid.
  void rejectConfigurations(bool reject);

  /// `frames` sensor frames of the running camera `id`, on the manager's thread (one frame
  /// period of virtual time each); waits until they are done.
  void produce(const std::string& id, int frames);
  /// The next `frames` sensor frames are dropped by the sensor (sequence gap).
  void skipFrames(int frames) { skip_frames_ = frames; }
  /// The frame of content index `index` completes with FrameMetadata::FrameError.
  void flagError(std::uint64_t index);
  /// Frames produced every `period` of real time until stopFreeRunning().
  void startFreeRunning(const std::string& id, std::chrono::microseconds period);
  void stopFreeRunning();

  /// Time the consumer spends elsewhere (virtual).
  void advance(std::int64_t ns);
  /// Steps the wall clock (an NTP correction).
  void stepRealtime(std::int64_t ns);
  /// Every `every`-th CLOCK_REALTIME read is preceded by a `delay_ns` stall (preemption
  /// between the bracketing reads); 0 turns it off.
  void delayRealtimeReads(int every, std::int64_t delay_ns);

  // ---- inspection -------------------------------------------------------------------
  /// The grey image of content index `index` at `size` (content index: frames produced,
  /// across cameras and streams).
  static cv::Mat expectedGrey(std::uint64_t index, cv::Size size);
  /// Content index of the frame whose SensorTimestamp is `boottime_ns`; -1.
  std::int64_t contentIndexAt(std::int64_t boottime_ns) const;
  /// CLOCK_BOOTTIME of the frame of content index `index` (its SensorTimestamp); -1.
  std::int64_t boottimeOf(std::uint64_t index) const;
  std::uint64_t framesProduced() const;
  std::int64_t realtimeOffsetNs() const;
  std::int64_t boottimeOffsetNs() const { return suspended_ns_; }
  /// Virtual CLOCK_MONOTONIC times of every cameras() call (each open or reopen attempt).
  std::vector<std::int64_t> openAttempts() const;
  std::vector<std::string> violations() const;
  void violation(std::string text);
  /// Mappings of the fake's memfds in this process (/proc/self/maps), the source's included.
  static int memfdMappings();

  // ---- libcam::CameraManager ----------------------------------------------------------
  std::vector<std::shared_ptr<libcam::Camera>> cameras() override;
  std::int64_t clockNs(clockid_t clock) override;

 private:
  friend class FakeCamera;
  void run();
  void post(std::function<void()> task, bool wait);
  void checkSchedule();                   // clock_m_ not held
  std::int64_t monotonicLocked() const { return now_ns_; }
  std::int64_t advanceFrame(std::int64_t period_ns);  // returns the boottime of the frame

  mutable std::mutex m_;  // cameras, scripting
  std::vector<std::shared_ptr<FakeCamera>> cameras_;
  std::vector<FakeCameraConfig> known_;  // last config per id
  bool busy_ = false;
  bool reject_ = false;
  std::string replug_id_;
  std::int64_t replug_at_ns_ = 0;
  std::vector<std::uint64_t> error_indices_;
  std::vector<std::pair<std::int64_t, std::uint64_t>> history_;  // (boottime, content index)
  std::uint64_t produced_ = 0;
  int skip_frames_ = 0;
  std::chrono::microseconds cancel_delay_{0};
  std::vector<std::int64_t> open_attempts_;

  mutable std::mutex clock_m_;
  std::int64_t now_ns_ = 5'000'000'000'000;           // 5000 s of monotonic uptime
  std::int64_t suspended_ns_ = 120'000'000'000;       // boottime runs 120 s ahead
  std::int64_t realtime_offset_ns_ = 1'700'000'000'123'456'789;
  std::int64_t read_cost_ns_ = 40;
  std::uint64_t realtime_reads_ = 0;
  int realtime_delay_every_ = 0;
  std::int64_t realtime_delay_ns_ = 0;

  mutable std::mutex violations_m_;
  std::vector<std::string> violations_;

  std::mutex task_m_;
  std::condition_variable task_cv_;
  std::deque<std::pair<std::function<void()>, std::shared_ptr<bool>>> tasks_;
  std::condition_variable done_cv_;
  bool quit_ = false;
  std::string free_running_id_;
  std::chrono::microseconds free_running_period_{0};
  std::thread thread_;  // libcamera's thread: completions and disconnects come from here
};

}  // namespace omnipose::testing
