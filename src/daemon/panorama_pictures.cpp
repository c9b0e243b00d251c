#include "daemon/panorama_pictures.hpp"

#include <pthread.h>
#include <sched.h>
#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "omnipose/panorama_image_t.hpp"

namespace omnipose::daemon {

cv::Size PanoramaPictures::pictureSize(cv::Size panorama, int width) {
  const int w = std::clamp(width, 1, panorama.width);
  const int h = std::max(1, static_cast<int>(std::lround(static_cast<double>(panorama.height) *
                                                        w / panorama.width)));
  return {w, h};
}

PanoramaPictures::PanoramaPictures(const Calibration& calibration, InputKind input, double hz,
                                   int width)
    : unwrapper_(calibration, {.input = input}),
      frame_(unwrapper_.inputSize(), CV_8UC1),
      panorama_(unwrapper_.makePanorama()),
      period_us_(static_cast<std::int64_t>(std::llround(1e6 / hz))),
      picture_size_(pictureSize(unwrapper_.panoramaSize(), width)),
      message_(std::make_unique<panorama_image_t>()) {
  message_->format = "jpeg";
  message_->width = static_cast<std::int16_t>(picture_size_.width);
  message_->height = static_cast<std::int16_t>(picture_size_.height);
  thread_ = std::thread([this] { run(); });
}

PanoramaPictures::~PanoramaPictures() {
  {
    std::lock_guard<std::mutex> lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  thread_.join();
}

bool PanoramaPictures::offer(const cv::Mat& frame, std::int64_t utime_us, std::int64_t sequence) {
  const bool due = !any_taken_ || utime_us - last_utime_us_ >= period_us_ ||
                   utime_us < last_utime_us_;  // the capture clock went back
  if (!due || frame.size() != frame_.size() || frame.type() != frame_.type()) return false;
  {
    std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
    if (!lock.owns_lock() || state_ != State::kIdle) return false;
    frame.copyTo(frame_);  // same size and type: no allocation
    utime_us_ = utime_us;
    sequence_ = sequence;
    state_ = State::kPending;
  }
  wake_.notify_one();
  any_taken_ = true;
  last_utime_us_ = utime_us;
  return true;
}

std::span<const std::uint8_t> PanoramaPictures::ready() const {
  std::unique_lock<std::mutex> lock(mutex_, std::try_to_lock);
  if (!lock.owns_lock() || state_ != State::kReady) return {};
  return encoded_;
}

void PanoramaPictures::done() {
  std::lock_guard<std::mutex> lock(mutex_);
  if (state_ == State::kReady) state_ = State::kIdle;
}

std::int64_t PanoramaPictures::made() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return made_;
}

std::int64_t PanoramaPictures::failed() const {
  std::lock_guard<std::mutex> lock(mutex_);
  return failed_;
}

bool PanoramaPictures::makePicture() {
  if (!unwrapper_.unwrap(frame_, panorama_)) return false;  // a black frame: no picture
  cv::resize(panorama_, small_, picture_size_, 0, 0, cv::INTER_AREA);
  small_.convertTo(grey_, CV_8U);  // saturating
  if (!cv::imencode(".jpg", grey_, jpeg_, {cv::IMWRITE_JPEG_QUALITY, kJpegQuality})) return false;
  panorama_image_t& m = *message_;
  m.utime = utime_us_;
  m.sequence = sequence_;
  m.size = static_cast<std::int32_t>(jpeg_.size());
  m.data.assign(jpeg_.begin(), jpeg_.end());
  encoded_.resize(static_cast<std::size_t>(m.getEncodedSize()));
  return m.encode(encoded_.data(), 0, static_cast<int>(encoded_.size())) > 0;
}

void PanoramaPictures::run() {
  // Below the pipeline whatever the daemon's scheduling: normal policy, niceness 10.
  sched_param normal{};
  pthread_setschedparam(pthread_self(), SCHED_OTHER, &normal);
  setpriority(PRIO_PROCESS, static_cast<id_t>(gettid()), 10);
  std::unique_lock<std::mutex> lock(mutex_);
  while (true) {
    wake_.wait(lock, [this] { return stop_ || state_ == State::kPending; });
    if (stop_) return;
    lock.unlock();  // the frame is the thread's until it sets the state
    const bool ok = makePicture();
    lock.lock();
    if (ok) {
      ++made_;
      state_ = State::kReady;
    } else {
      ++failed_;
      state_ = State::kIdle;
    }
  }
}

}  // namespace omnipose::daemon
