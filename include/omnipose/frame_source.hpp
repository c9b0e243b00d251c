#pragma once
/// \file frame_source.hpp
/// Where frames come from: a recorded dataset directory, a V4L2 device or a libcamera
/// camera, behind one interface. Every source delivers 8-bit grey frames (colour and YUV
/// are converted by the source) with a capture timestamp on the wall clock and a
/// sequence number; every expected failure is a value, never an exception.
///
/// Threading: a source is driven by one thread (the capture thread). next() writes into a
/// buffer the caller owns, so a capture thread can fill preallocated slots and hand them
/// to the processing thread without allocating.

#include <chrono>
#include <cstdint>
#include <limits>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "omnipose/error.hpp"

namespace omnipose {

/// Metadata of one delivered frame.
struct FrameInfo {
  std::int64_t capture_time_us = 0;  ///< capture time, wall clock (CLOCK_REALTIME), microseconds
  /// The same on CLOCK_MONOTONIC, a clock that does not jump: what the odometry times frames
  /// by and the gyro's samples are joined to (DESIGN.md section 6). 0: the source has none
  /// (file sources: their recorded timestamps are used).
  std::int64_t steady_time_us = 0;
  std::uint64_t sequence = 0;        ///< source's frame counter (gaps = frames lost upstream)
  double source_timestamp = 0.0;     ///< file sources: the recorded timestamp, seconds
  int index = -1;                    ///< file sources: frame index in the dataset
  /// How long the frame's rows were exposed, seconds, as the camera reported it for this
  /// frame (libcamera's ExposureTime; a dataset's timestamps.txt); NaN: not reported.
  double exposure_s = std::numeric_limits<double>::quiet_NaN();
  /// The source's clock jumped forward by more than its pacing bound before this frame (a
  /// recording with a gap in its timestamps): pacing was resynchronised to this frame
  /// instead of waiting the gap out. The capture loop reports it.
  bool resynchronised = false;
};

class FrameSource {
 public:
  virtual ~FrameSource() = default;

  /// Opens the device/directory and negotiates the format. Errors: kNotFound /
  /// kNoDevice (nothing at the path / no camera), kBusy (in use), kUnsupportedFormat,
  /// kIoError. The message names the device or path.
  virtual Expected<void> open() = 0;

  /// Frame size delivered by next(); valid after a successful open().
  virtual cv::Size frameSize() const = 0;

  /// Waits up to `timeout` for the next frame and writes it as CV_8UC1 into `out`, which
  /// must already be frameSize() and CV_8UC1 (it is never reallocated). Errors:
  /// kTimeout (nothing yet, call again), kBadFrame (this frame was unusable and dropped:
  /// corrupt, wrong size, flagged by the driver; call again), kDisconnected (device or
  /// directory gone, or the stream broke: a camera source has released the device and
  /// keeps answering kDisconnected; close() and open() the source again, with a back-off,
  /// to go on; no source retries on its own), kEndOfStream (a finite source is done).
  virtual Expected<FrameInfo> next(cv::Mat& out, std::chrono::milliseconds timeout) = 0;

  /// Stops streaming and releases the device. Safe to call twice.
  virtual void close() = 0;

  /// One line naming the source for logs and status ("v4l2 /dev/video0 1280x720 YUYV").
  virtual std::string describe() const = 0;
  /// What open() noticed that a user should know but that does not stop the source (a
  /// recording's timestamps going backwards, say), one message each. Empty by default.
  virtual std::vector<std::string> warnings() const { return {}; }

  /// The sequence number the first frame after the last open() carries when nothing is
  /// dropped before it, so that frames passed over before the first delivered one are
  /// counted as lost. std::nullopt when the source cannot know (a camera whose driver
  /// numbers frames from an unknown start): then only gaps between delivered frames count.
  virtual std::optional<std::uint64_t> sequenceOrigin() const { return std::nullopt; }
};

}  // namespace omnipose
