#include "fake_libcamera.hpp"

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdlib>
#include <cstring>
#include <fstream>

namespace omnipose::testing {
namespace {

constexpr std::uint8_t kPadding = 0xEE;   // stride padding bytes
constexpr std::uint8_t kScribble = 0xA5;  // what a freshly queued buffer holds
constexpr const char* kMemfdName = "omnipose-fake-libcamera";

unsigned alignUp(unsigned n, unsigned a) { return a <= 1 ? n : (n + a - 1) / a * a; }

/// Bytes per pixel of plane 0's rows.
unsigned rowBytesPerPixel(std::uint32_t fourcc) {
  if (fourcc == kFakeYUYV) return 2;
  if (fourcc == kFakeXRGB) return 4;
  return 1;
}

unsigned frameBytes(std::uint32_t fourcc, unsigned stride, unsigned height) {
  return fourcc == kFakeNV12 ? stride * height + stride * ((height + 1) / 2) : stride * height;
}

}  // namespace

// ---------------------------------------------------------------------------------------
// FakeCamera
// ---------------------------------------------------------------------------------------

FakeCamera::FakeCamera(FakeCameraManager& manager, FakeCameraConfig config)
    : manager_(manager), config_(std::move(config)) {}

FakeCamera::~FakeCamera() {
  if (!buffers_.empty()) manager_.violation(config_.id + ": camera destroyed with buffers allocated");
  for (Buffer& b : buffers_) {
    ::munmap(b.map, b.size);
    ::close(b.fd);
  }
}

int FakeCamera::access(bool allow_disconnected) const {
  return !allow_disconnected && disconnected_ ? -ENODEV : 0;
}

int FakeCamera::acquire() {
  std::lock_guard lock(m_);
  if (const int r = access(false)) return r;
  if (state_ != State::kAvailable) return -EBUSY;
  {
    std::lock_guard mlock(manager_.m_);
    if (manager_.busy_) return -EBUSY;
  }
  state_ = State::kAcquired;
  return 0;
}

int FakeCamera::release() {
  std::lock_guard lock(m_);
  if (state_ == State::kRunning) {
    manager_.violation(config_.id + ": release() while running");
    return -EBUSY;
  }
  if (state_ == State::kAvailable) return 0;
  if (!buffers_.empty()) manager_.violation(config_.id + ": release() with buffers allocated");
  state_ = State::kAvailable;
  have_validated_ = false;
  return 0;
}

bool FakeCamera::generateVideoConfiguration(libcam::StreamSettings& settings,
                                            std::vector<std::uint32_t>& offered) {
  std::lock_guard lock(m_);
  if (access(false) != 0 || config_.formats.empty() || config_.sizes.empty()) return false;
  offered = config_.formats;
  settings = {};
  settings.fourcc = config_.formats.front();
  settings.width = static_cast<unsigned>(config_.sizes.front().width);
  settings.height = static_cast<unsigned>(config_.sizes.front().height);
  settings.buffer_count = 4;
  settings.stride = alignUp(settings.width * rowBytesPerPixel(settings.fourcc), config_.stride_align);
  settings.frame_size = frameBytes(settings.fourcc, settings.stride, settings.height);
  return true;
}

libcam::ConfigStatus FakeCamera::validate(libcam::StreamSettings& s) {
  {
    std::lock_guard mlock(manager_.m_);
    if (manager_.reject_) return libcam::ConfigStatus::kInvalid;
  }
  std::lock_guard lock(m_);
  bool adjusted = false;
  if (std::find(config_.formats.begin(), config_.formats.end(), s.fourcc) == config_.formats.end()) {
    s.fourcc = config_.formats.front();
    adjusted = true;
  }
  const cv::Size asked(static_cast<int>(s.width), static_cast<int>(s.height));
  cv::Size best = config_.sizes.front();
  for (const cv::Size& c : config_.sizes)
    if (std::abs(c.width - asked.width) + std::abs(c.height - asked.height) <
        std::abs(best.width - asked.width) + std::abs(best.height - asked.height))
      best = c;
  if (best != asked) {
    s.width = static_cast<unsigned>(best.width);
    s.height = static_cast<unsigned>(best.height);
    adjusted = true;
  }
  const unsigned count = std::clamp(s.buffer_count, config_.min_buffers, config_.max_buffers);
  if (count != s.buffer_count) {
    s.buffer_count = count;
    adjusted = true;
  }
  s.stride = alignUp(s.width * rowBytesPerPixel(s.fourcc), config_.stride_align);
  s.frame_size = frameBytes(s.fourcc, s.stride, s.height);
  validated_ = s;
  have_validated_ = true;
  return adjusted ? libcam::ConfigStatus::kAdjusted : libcam::ConfigStatus::kValid;
}

int FakeCamera::configure() {
  libcam::StreamSettings check;
  {
    std::lock_guard lock(m_);
    if (const int r = access(false)) return r;
    if (state_ != State::kAcquired && state_ != State::kConfigured) {
      manager_.violation(config_.id + ": configure() when not acquired or running");
      return -EACCES;
    }
    if (!have_validated_) return -EINVAL;
    if (!buffers_.empty()) {
      manager_.violation(config_.id + ": configure() with buffers allocated");
      return -EBUSY;
    }
    check = validated_;
  }
  // libcamera validates again; an adjusted configuration read back is Valid.
  if (validate(check) != libcam::ConfigStatus::kValid) return -EINVAL;
  std::lock_guard lock(m_);
  state_ = State::kConfigured;
  return 0;
}

int FakeCamera::allocate(std::vector<std::vector<libcam::BufferPlane>>& out) {
  std::lock_guard lock(m_);
  if (const int r = access(false)) return r;
  if (state_ != State::kConfigured) {
    manager_.violation(config_.id + ": allocate() when not configured");
    return -EACCES;
  }
  if (!buffers_.empty()) {
    manager_.violation(config_.id + ": allocate() twice");
    return -EBUSY;
  }
  const libcam::StreamSettings& s = validated_;
  out.clear();
  for (unsigned i = 0; i < s.buffer_count; ++i) {
    Buffer b;
    b.size = s.frame_size;
    b.fd = ::memfd_create(kMemfdName, MFD_CLOEXEC);
    if (b.fd < 0 || ::ftruncate(b.fd, static_cast<off_t>(b.size)) != 0) return -ENOMEM;
    void* map = ::mmap(nullptr, b.size, PROT_READ | PROT_WRITE, MAP_SHARED, b.fd, 0);
    if (map == MAP_FAILED) return -ENOMEM;
    b.map = static_cast<std::uint8_t*>(map);
    std::memset(b.map, kScribble, b.size);
    buffers_.push_back(b);
    if (s.fourcc == kFakeNV12)
      out.push_back({{b.fd, 0, s.stride * s.height},
                     {b.fd, s.stride * s.height, s.frame_size - s.stride * s.height}});
    else
      out.push_back({{b.fd, 0, s.frame_size}});
  }
  queued_.assign(buffers_.size(), false);
  return static_cast<int>(buffers_.size());
}

int FakeCamera::start(std::int64_t frame_duration_us) {
  std::lock_guard lock(m_);
  if (const int r = access(false)) return r;
  if (state_ != State::kConfigured) {
    manager_.violation(config_.id + ": start() when not configured");
    return -EACCES;
  }
  if (frame_duration_us > 0 && !config_.frame_duration_settable)
    manager_.violation(config_.id + ": FrameDurationLimits set, not among the camera's controls");
  frame_duration_us_ = frame_duration_us;
  sequence_ = 0;
  state_ = State::kRunning;
  ++start_count_;
  return 0;
}

int FakeCamera::queueRequest(std::uint64_t cookie) {
  std::lock_guard lock(m_);
  if (const int r = access(false)) return r;
  if (state_ != State::kRunning) return -EACCES;
  if (cookie >= buffers_.size()) {
    manager_.violation(config_.id + ": queueRequest() of an unknown request");
    return -EINVAL;
  }
  if (queued_[cookie]) {
    manager_.violation(config_.id + ": request " + std::to_string(cookie) + " queued twice");
    return -EINVAL;
  }
  queued_[cookie] = true;
  std::memset(buffers_[cookie].map, kScribble, buffers_[cookie].size);
  ring_[(ring_head_ + ring_count_++) % 64] = cookie;
  return 0;
}

int FakeCamera::stop() {
  {
    std::lock_guard lock(m_);
    if (state_ != State::kRunning) return 0;
    state_ = State::kConfigured;
  }
  // Blocking invocation on the pipeline thread: every pending request completes, cancelled.
  manager_.post([this] { cancelPending(); }, true);
  return 0;
}

void FakeCamera::freeBuffers() {
  std::lock_guard lock(m_);
  if (state_ == State::kRunning) manager_.violation(config_.id + ": buffers freed while running");
  if (ring_count_ != 0)
    manager_.violation(config_.id + ": buffers freed with requests pending");
  for (Buffer& b : buffers_) {
    ::munmap(b.map, b.size);
    ::close(b.fd);
  }
  buffers_.clear();
  queued_.clear();
  ring_head_ = ring_count_ = 0;
}

void FakeCamera::setListener(libcam::CameraListener* listener) {
  std::lock_guard lock(listener_mutex_);
  listener_ = listener;
}

void FakeCamera::deliver(const libcam::Completion& completion) {
  std::lock_guard lock(listener_mutex_);
  if (listener_ != nullptr) listener_->requestCompleted(completion);
}

void FakeCamera::produceFrame(std::uint64_t content_index, bool flag_error) {
  libcam::Completion c;
  {
    std::lock_guard lock(m_);
    if (state_ != State::kRunning) return;
    const std::int64_t period = frame_duration_us_ > 0 ? frame_duration_us_ * 1000
                                                       : config_.default_frame_duration_ns;
    const std::int64_t boottime = manager_.advanceFrame(period);
    {
      std::lock_guard mlock(manager_.m_);
      manager_.history_.emplace_back(boottime, content_index);
    }
    const std::uint32_t seq = sequence_++;
    if (ring_count_ == 0) return;  // no request: the frame is lost
    const std::uint64_t cookie = ring_[ring_head_];
    ring_head_ = (ring_head_ + 1) % 64;
    --ring_count_;
    queued_[cookie] = false;

    // The frame: luma from expectedGrey(), chroma that differs from it, padding.
    const libcam::StreamSettings& s = validated_;
    const cv::Size size(static_cast<int>(s.width), static_cast<int>(s.height));
    const cv::Mat grey = FakeCameraManager::expectedGrey(content_index, size);
    std::uint8_t* data = buffers_[cookie].map;
    std::memset(data, kPadding, buffers_[cookie].size);
    for (int y = 0; y < size.height; ++y) {
      std::uint8_t* row = data + static_cast<std::size_t>(y) * s.stride;
      const std::uint8_t* g = grey.ptr<std::uint8_t>(y);
      if (s.fourcc == kFakeYUYV) {
        for (int x = 0; x < size.width; ++x) {
          row[2 * x] = g[x];
          row[2 * x + 1] = static_cast<std::uint8_t>(0x80 ^ (x & 0x3F) ^ (y << 2));
        }
      } else if (s.fourcc == kFakeXRGB) {
        for (int x = 0; x < size.width; ++x)
          for (int k = 0; k < 4; ++k) row[4 * x + k] = g[x];
      } else {
        std::memcpy(row, g, static_cast<std::size_t>(size.width));
      }
    }
    if (s.fourcc == kFakeNV12)
      for (int y = 0; y < (size.height + 1) / 2; ++y)
        std::memset(data + static_cast<std::size_t>(size.height + y) * s.stride, 0x40 + (y & 0x3F),
                    static_cast<std::size_t>(size.width));

    c.cookie = cookie;
    c.frame_ok = !flag_error;
    c.sequence = seq;
    c.timestamp_ns = static_cast<std::uint64_t>(boottime);
    c.bytes_used = s.frame_size;
    c.has_sensor_timestamp = config_.sensor_timestamp;
    c.sensor_timestamp_ns = config_.sensor_timestamp ? boottime : 0;
    c.has_exposure_time = !config_.exposure_time_us.empty();
    if (c.has_exposure_time)
      c.exposure_time_us = config_.exposure_time_us[seq % config_.exposure_time_us.size()];
  }
  deliver(c);
}

void FakeCamera::cancelPending() {
  for (;;) {
    libcam::Completion c;
    {
      std::lock_guard lock(m_);
      if (ring_count_ == 0) return;
      c.cookie = ring_[ring_head_];
      ring_head_ = (ring_head_ + 1) % 64;
      --ring_count_;
      queued_[c.cookie] = false;
      c.cancelled = true;
    }
    deliver(c);
  }
}

void FakeCamera::disconnectNow() {
  {
    std::lock_guard lock(m_);
    disconnected_ = true;
    if (state_ == State::kRunning) state_ = State::kConfigured;
  }
  {
    std::lock_guard lock(listener_mutex_);
    if (listener_ != nullptr) listener_->disconnected();
  }
  std::chrono::microseconds delay;
  {
    std::lock_guard lock(manager_.m_);
    delay = manager_.cancel_delay_;
  }
  if (delay.count() > 0) std::this_thread::sleep_for(delay);
  cancelPending();
}

bool FakeCamera::running() const {
  std::lock_guard lock(m_);
  return state_ == State::kRunning;
}
bool FakeCamera::acquired() const {
  std::lock_guard lock(m_);
  return state_ != State::kAvailable;
}
bool FakeCamera::disconnectedFlag() const {
  std::lock_guard lock(m_);
  return disconnected_;
}
int FakeCamera::pendingRequests() const {
  std::lock_guard lock(m_);
  return ring_count_;
}
int FakeCamera::allocatedBuffers() const {
  std::lock_guard lock(m_);
  return static_cast<int>(buffers_.size());
}
libcam::StreamSettings FakeCamera::configured() const {
  std::lock_guard lock(m_);
  return validated_;
}
std::int64_t FakeCamera::frameDurationUs() const {
  std::lock_guard lock(m_);
  return frame_duration_us_;
}
int FakeCamera::startCount() const {
  std::lock_guard lock(m_);
  return start_count_;
}

// ---------------------------------------------------------------------------------------
// FakeCameraManager
// ---------------------------------------------------------------------------------------

FakeCameraManager::FakeCameraManager() {
  history_.reserve(1 << 16);
  thread_ = std::thread([this] { run(); });
}

FakeCameraManager::~FakeCameraManager() {
  {
    std::lock_guard lock(task_m_);
    quit_ = true;
  }
  task_cv_.notify_all();
  thread_.join();
  cameras_.clear();  // before the members their destructors use
}

std::function<Expected<std::shared_ptr<libcam::CameraManager>>()> FakeCameraManager::opener(
    std::shared_ptr<FakeCameraManager> manager) {
  return [manager]() -> Expected<std::shared_ptr<libcam::CameraManager>> { return manager; };
}

void FakeCameraManager::run() {
  std::unique_lock lock(task_m_);
  for (;;) {
    if (quit_) return;
    if (tasks_.empty()) {
      if (free_running_period_.count() > 0) {
        task_cv_.wait_for(lock, free_running_period_);
        if (tasks_.empty() && !quit_ && free_running_period_.count() > 0) {
          const std::string id = free_running_id_;
          lock.unlock();
          produce(id, 1);
          lock.lock();
        }
      } else {
        task_cv_.wait(lock);
      }
      continue;
    }
    auto task = std::move(tasks_.front());
    tasks_.pop_front();
    lock.unlock();
    task.first();
    lock.lock();
    if (task.second) *task.second = true;
    done_cv_.notify_all();
  }
}

void FakeCameraManager::post(std::function<void()> task, bool wait) {
  if (std::this_thread::get_id() == thread_.get_id()) {  // already on the pipeline thread
    task();
    return;
  }
  auto done = wait ? std::make_shared<bool>(false) : nullptr;
  std::unique_lock lock(task_m_);
  tasks_.emplace_back(std::move(task), done);
  task_cv_.notify_all();
  if (wait) done_cv_.wait(lock, [&] { return *done; });
}

std::shared_ptr<FakeCamera> FakeCameraManager::plug(FakeCameraConfig config) {
  auto camera = std::make_shared<FakeCamera>(*this, config);
  std::lock_guard lock(m_);
  cameras_.push_back(camera);
  auto known = std::find_if(known_.begin(), known_.end(),
                            [&](const FakeCameraConfig& k) { return k.id == config.id; });
  if (known == known_.end()) known_.push_back(std::move(config));
  else *known = std::move(config);
  return camera;
}

void FakeCameraManager::unplug(const std::string& id) {
  post(
      [this, id] {
        std::shared_ptr<FakeCamera> gone;
        {
          std::lock_guard lock(m_);
          auto it = std::find_if(cameras_.begin(), cameras_.end(),
                                 [&](const auto& c) { return c->id() == id; });
          if (it == cameras_.end()) return;
          gone = *it;
          cameras_.erase(it);  // cameraRemoved
        }
        gone->disconnectNow();
      },
      true);
}

std::shared_ptr<FakeCamera> FakeCameraManager::replug(const std::string& id) {
  FakeCameraConfig config;
  {
    std::lock_guard lock(m_);
    auto known = std::find_if(known_.begin(), known_.end(),
                              [&](const FakeCameraConfig& k) { return k.id == id; });
    if (known == known_.end()) return nullptr;
    config = *known;
    if (replug_id_ == id) replug_at_ns_ = 0;
  }
  return plug(std::move(config));
}

void FakeCameraManager::setCancelDelayAfterDisconnect(std::chrono::microseconds delay) {
  std::lock_guard lock(m_);
  cancel_delay_ = delay;
}

void FakeCameraManager::scheduleReplug(const std::string& id, std::int64_t at_ns) {
  std::lock_guard lock(m_);
  replug_id_ = id;
  replug_at_ns_ = at_ns;
}

void FakeCameraManager::checkSchedule() {
  std::string id;
  {
    std::lock_guard clock(clock_m_);
    std::lock_guard lock(m_);
    if (replug_at_ns_ == 0 || now_ns_ < replug_at_ns_) return;
    replug_at_ns_ = 0;
    id = replug_id_;
  }
  replug(id);
}

std::shared_ptr<FakeCamera> FakeCameraManager::camera(const std::string& id) const {
  std::lock_guard lock(m_);
  for (const auto& c : cameras_)
    if (c->id() == id) return c;
  return nullptr;
}

void FakeCameraManager::setBusy(bool busy) {
  std::lock_guard lock(m_);
  busy_ = busy;
}

void FakeCameraManager::rejectConfigurations(bool reject) {
  std::lock_guard lock(m_);
  reject_ = reject;
}

void FakeCameraManager::produce(const std::string& id, int frames) {
  post(
      [this, id, frames] {
        auto c = camera(id);
        for (int i = 0; i < frames; ++i) {
          std::uint64_t index;
          bool error;
          int skip;
          {
            std::lock_guard lock(m_);
            skip = skip_frames_;
            skip_frames_ = 0;
          }
          if (c) {  // the sensor drops `skip` frames: their sequence numbers pass unused
            std::lock_guard lock(c->m_);
            c->sequence_ += static_cast<std::uint32_t>(skip);
          }
          {
            std::lock_guard lock(m_);
            index = produced_++;
            error = std::find(error_indices_.begin(), error_indices_.end(), index) !=
                    error_indices_.end();
          }
          if (c) c->produceFrame(index, error);
        }
      },
      true);
}

void FakeCameraManager::flagError(std::uint64_t index) {
  std::lock_guard lock(m_);
  error_indices_.push_back(index);
}

void FakeCameraManager::startFreeRunning(const std::string& id, std::chrono::microseconds period) {
  {
    std::lock_guard lock(task_m_);
    free_running_id_ = id;
    free_running_period_ = period;
  }
  task_cv_.notify_all();
}

void FakeCameraManager::stopFreeRunning() {
  // Waits for a frame in production to finish (the task queue runs in order).
  {
    std::lock_guard lock(task_m_);
    free_running_period_ = std::chrono::microseconds(0);
  }
  post([] {}, true);
}

std::int64_t FakeCameraManager::advanceFrame(std::int64_t period_ns) {
  std::lock_guard lock(clock_m_);
  now_ns_ += period_ns;
  return now_ns_ + suspended_ns_;
}

void FakeCameraManager::advance(std::int64_t ns) {
  {
    std::lock_guard lock(clock_m_);
    now_ns_ += ns;
  }
  checkSchedule();
}

void FakeCameraManager::stepRealtime(std::int64_t ns) {
  std::lock_guard lock(clock_m_);
  realtime_offset_ns_ += ns;
}

void FakeCameraManager::delayRealtimeReads(int every, std::int64_t delay_ns) {
  std::lock_guard lock(clock_m_);
  realtime_delay_every_ = every;
  realtime_delay_ns_ = delay_ns;
}

cv::Mat FakeCameraManager::expectedGrey(std::uint64_t index, cv::Size size) {
  cv::Mat m(size, CV_8UC1);
  const int k = static_cast<int>(index % 251);
  for (int y = 0; y < size.height; ++y)
    for (int x = 0; x < size.width; ++x)
      m.at<std::uint8_t>(y, x) = static_cast<std::uint8_t>((x * 3 + y * 5 + k * 37 + (x * y) / 7) & 0xFF);
  return m;
}

std::int64_t FakeCameraManager::contentIndexAt(std::int64_t boottime_ns) const {
  std::lock_guard lock(m_);
  for (const auto& [t, index] : history_)
    if (t == boottime_ns) return static_cast<std::int64_t>(index);
  return -1;
}

std::int64_t FakeCameraManager::boottimeOf(std::uint64_t index) const {
  std::lock_guard lock(m_);
  for (const auto& [t, i] : history_)
    if (i == index) return t;
  return -1;
}

std::uint64_t FakeCameraManager::framesProduced() const {
  std::lock_guard lock(m_);
  return produced_;
}

std::int64_t FakeCameraManager::realtimeOffsetNs() const {
  std::lock_guard lock(clock_m_);
  return realtime_offset_ns_;
}

std::vector<std::int64_t> FakeCameraManager::openAttempts() const {
  std::lock_guard lock(m_);
  return open_attempts_;
}

std::vector<std::string> FakeCameraManager::violations() const {
  std::lock_guard lock(violations_m_);
  return violations_;
}

void FakeCameraManager::violation(std::string text) {
  std::lock_guard lock(violations_m_);
  violations_.push_back(std::move(text));
}

int FakeCameraManager::memfdMappings() {
  std::ifstream maps("/proc/self/maps");
  int n = 0;
  for (std::string line; std::getline(maps, line);)
    if (line.find(kMemfdName) != std::string::npos) ++n;
  return n;
}

std::vector<std::shared_ptr<libcam::Camera>> FakeCameraManager::cameras() {
  checkSchedule();
  std::int64_t now;
  {
    std::lock_guard lock(clock_m_);
    now = now_ns_;
  }
  std::lock_guard lock(m_);
  open_attempts_.push_back(now);
  return {cameras_.begin(), cameras_.end()};
}

std::int64_t FakeCameraManager::clockNs(clockid_t clock) {
  std::int64_t t;
  {
    std::lock_guard lock(clock_m_);
    now_ns_ += read_cost_ns_;
    if (clock == CLOCK_REALTIME && realtime_delay_every_ > 0 &&
        ++realtime_reads_ % static_cast<std::uint64_t>(realtime_delay_every_) == 0)
      now_ns_ += realtime_delay_ns_;
    switch (clock) {
      case CLOCK_MONOTONIC: t = now_ns_; break;
      case CLOCK_BOOTTIME: t = now_ns_ + suspended_ns_; break;
      case CLOCK_REALTIME: t = now_ns_ + suspended_ns_ + realtime_offset_ns_; break;
      default: t = -1;
    }
  }
  checkSchedule();
  return t;
}

}  // namespace omnipose::testing
