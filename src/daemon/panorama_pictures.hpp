#pragma once
/// \file panorama_pictures.hpp
/// Small panorama pictures for a viewer (daemon.yaml lcm.panorama_channel, omnipose-view):
/// at most `hz` per second of capture time, a frame is copied by the processing thread (its
/// only cost: one memcpy of the grey frame, into a buffer allocated once) and a thread of its
/// own, at normal scheduling and niceness 10 whatever the daemon's, unwraps it with an
/// Unwrapper of its own, shrinks it to at most `width` columns (area average), JPEG-encodes it
/// and fills an omnipose::panorama_image_t. The processing thread publishes the encoded
/// message at a later frame (ready(), then done()). It never waits: a frame offered while a
/// picture is still being made or not yet published is not taken.
/// The picture thread allocates (the JPEG encoder); the processing thread's calls do not.

#include <condition_variable>
#include <cstdint>
#include <memory>
#include <mutex>
#include <opencv2/core.hpp>
#include <span>
#include <thread>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/unwrapper.hpp"

namespace omnipose {
class panorama_image_t;
}  // namespace omnipose

namespace omnipose::daemon {

class PanoramaPictures {
 public:
  /// JPEG quality of the pictures (1..100).
  static constexpr int kJpegQuality = 80;

  /// Builds the unwrapper (throws std::invalid_argument like Unwrapper) and starts the
  /// thread. `hz` in (0, 30], `width` >= 1 (daemon.yaml checks both).
  PanoramaPictures(const Calibration& calibration, InputKind input, double hz, int width);
  ~PanoramaPictures();  ///< stops and joins the thread
  PanoramaPictures(const PanoramaPictures&) = delete;
  PanoramaPictures& operator=(const PanoramaPictures&) = delete;

  // --- processing thread ---------------------------------------------------------------
  /// `frame` (CV_8UC1, the input size) captured at `utime_us`: copied for a picture when one
  /// is due (1/hz after the last one taken, or the capture clock went back) and the picture
  /// thread is idle. Returns whether it was taken.
  bool offer(const cv::Mat& frame, std::int64_t utime_us, std::int64_t sequence);
  /// The encoded panorama_image_t made since the last done(), or an empty span.
  std::span<const std::uint8_t> ready() const;
  /// The message ready() gave was published (or dropped): the thread may make the next.
  void done();

  /// The picture's size for a panorama of `panorama` size: at most `width` columns, the
  /// height in proportion (at least 1 row).
  static cv::Size pictureSize(cv::Size panorama, int width);
  /// Pictures made since construction, and those the encoder failed on (none published).
  std::int64_t made() const;
  std::int64_t failed() const;

 private:
  enum class State { kIdle, kPending, kReady };
  void run();
  /// Unwraps, shrinks and encodes the pending frame into encoded_; false when it fails.
  bool makePicture();

  Unwrapper unwrapper_;
  cv::Mat frame_;      ///< the copied frame (processing thread writes it in kIdle)
  cv::Mat panorama_;   ///< picture thread
  cv::Mat small_, grey_;
  std::int64_t period_us_;
  cv::Size picture_size_;
  std::int64_t last_utime_us_ = 0;
  bool any_taken_ = false;
  std::int64_t utime_us_ = 0, sequence_ = 0;  ///< of the copied frame
  std::unique_ptr<panorama_image_t> message_;
  std::vector<std::uint8_t> jpeg_;
  std::vector<std::uint8_t> encoded_;

  mutable std::mutex mutex_;
  std::condition_variable wake_;
  State state_ = State::kIdle;  ///< guarded by mutex_
  bool stop_ = false;           ///< guarded by mutex_
  std::int64_t made_ = 0, failed_ = 0;  ///< guarded by mutex_
  std::thread thread_;
};

}  // namespace omnipose::daemon
