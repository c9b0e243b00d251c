#include "file/file_frame_source.hpp"

#include <opencv2/imgproc.hpp>
#include <thread>

#include "common/wall_clock.hpp"
#include "omnipose/image_decode.hpp"

namespace omnipose {
namespace fs = std::filesystem;
using drivers::wallClockMicros;

FileFrameSource::FileFrameSource(Options options) : options_(std::move(options)) {}

Expected<void> FileFrameSource::open() {
  std::error_code ec;
  if (!fs::is_directory(options_.directory, ec)) {
    return fail(ErrorCode::kNotFound, "%s: no such dataset directory",
                options_.directory.c_str());
  }
  try {
    std::optional<fs::path> override_calibration;
    if (!options_.calibration.empty()) override_calibration = options_.calibration;
    dataset_ = Dataset::open(options_.directory, override_calibration);
  } catch (const std::exception& e) {
    dataset_.reset();
    return fail(ErrorCode::kIoError, "%s", e.what());
  }
  if (next_index_ > dataset_->frames.size()) next_index_ = dataset_->frames.size();
  has_origin_ = false;  // pacing restarts from the moment of (re-)opening

  // Fail early when the frames cannot be what the pipeline expects (e.g. omni frames with
  // `input: panorama`): the size the first frame's header declares, nothing decoded. A frame
  // whose header cannot be read is left to next() (a bad frame).
  const std::size_t probe = next_index_ < dataset_->frames.size() ? next_index_ : 0;
  if (const Expected<ImageHeader> first =
          readImageHeader(dataset_->frames[probe].path, ImageLimits{}, bytes_);
      first && cv::Size(first->width, first->height) != options_.frame_size) {
    dataset_.reset();
    return fail(ErrorCode::kUnsupportedFormat, "%s: frames are %dx%d, expected %dx%d",
                options_.directory.c_str(), first->width, first->height,
                options_.frame_size.width, options_.frame_size.height);
  }
  return {};
}

void FileFrameSource::close() {
  dataset_.reset();
  has_origin_ = false;
}

int FileFrameSource::frameCount() const {
  return dataset_ ? static_cast<int>(dataset_->frames.size()) : 0;
}

std::string FileFrameSource::describe() const {
  std::string text = "file " + options_.directory.string();
  if (dataset_) text += " (" + std::to_string(dataset_->frames.size()) + " frames)";
  text += options_.realtime ? ", realtime" : ", as fast as processed";
  if (options_.loop) text += ", loop";
  if (dataset_) {
    if (const std::string assumed = dataset_->assumptions(); !assumed.empty())
      text += "; warning: " + assumed;
  }
  return text;
}

std::vector<std::string> FileFrameSource::warnings() const {
  return dataset_ ? dataset_->warnings : std::vector<std::string>{};
}

bool FileFrameSource::startOver() {
  if (!options_.loop) return false;
  const auto& frames = dataset_->frames;
  // Loop: frame 0 follows the last frame one mean frame interval later.
  if (has_origin_) {
    const double span = frames.back().timestamp - frames.front().timestamp;
    double period = frames.size() > 1 ? span / static_cast<double>(frames.size() - 1)
                                      : 1.0 / Dataset::kDefaultFps;
    if (!(period > 0)) period = 1.0 / Dataset::kDefaultFps;  // timestamps not increasing
    origin_wall_us_ += static_cast<std::int64_t>((frames.back().timestamp - origin_stamp_ +
                                                  period) * 1e6);
    origin_stamp_ = frames.front().timestamp;
  }
  next_index_ = 0;
  return true;
}

Expected<FileFrameSource::Due> FileFrameSource::pace(std::chrono::milliseconds timeout) {
  const auto& frames = dataset_->frames;
  Due due;
  if (!has_origin_) {
    origin_wall_us_ = wallClockMicros();
    origin_stamp_ = frames[next_index_].timestamp;
    has_origin_ = true;
  }
  // A frame stamped before its predecessor (a broken recording): pacing starts again
  // from it (it is due now) instead of treating every frame up to the old time as late.
  auto backwards = [&](std::size_t i) { return i > 0 && frames[i].timestamp < frames[i - 1].timestamp; };
  auto restartAt = [&](std::size_t i) {
    origin_wall_us_ = wallClockMicros();
    origin_stamp_ = frames[i].timestamp;
  };
  if (backwards(next_index_)) restartAt(next_index_);
  auto dueOf = [&](std::size_t i) {
    return origin_wall_us_ + static_cast<std::int64_t>((frames[i].timestamp - origin_stamp_) * 1e6);
  };
  // Running late (the reader was busy longer than a frame interval): like a camera,
  // deliver the frame that is current now; the ones missed in between are never read
  // (the sequence number jumps over them).
  const std::int64_t now_us = wallClockMicros();
  while (next_index_ + 1 < frames.size() && !backwards(next_index_ + 1) &&
         dueOf(next_index_ + 1) <= now_us) {
    ++next_index_;
    ++sequence_;
  }
  // A gap in the recording longer than the pacing bound (a jump in timestamps.txt, or a
  // loop whose mean interval such a jump inflated): pacing starts again from this frame,
  // which is due now, instead of the daemon sleeping through the gap.
  if (dueOf(next_index_) - now_us > static_cast<std::int64_t>(options_.max_pacing_gap_s * 1e6)) {
    restartAt(next_index_);
    due.resynchronised = true;
  }
  due.capture_us = dueOf(next_index_);
  const std::int64_t wait_us = due.capture_us - wallClockMicros();
  if (wait_us > std::chrono::duration_cast<std::chrono::microseconds>(timeout).count()) {
    std::this_thread::sleep_for(timeout);
    return fail(ErrorCode::kTimeout, "%s: next frame not due yet", options_.directory.c_str());
  }
  if (wait_us > 0) std::this_thread::sleep_for(std::chrono::microseconds(wait_us));
  return due;
}

Expected<void> FileFrameSource::toGrey(const DatasetFrame& frame, cv::Mat& out) const {
  if (out.size() != options_.frame_size || out.type() != CV_8UC1) {
    return fail(ErrorCode::kInvalidArgument, "output buffer must be %dx%d CV_8UC1",
                options_.frame_size.width, options_.frame_size.height);
  }
  uchar* const target = out.data;
  switch (decoded_.channels()) {
    case 1: decoded_.copyTo(out); break;
    case 3: cv::cvtColor(decoded_, out, cv::COLOR_BGR2GRAY); break;
    case 4: cv::cvtColor(decoded_, out, cv::COLOR_BGRA2GRAY); break;
    default:
      return fail(ErrorCode::kBadFrame, "%s: %d channels, expected 1, 3 or 4",
                  frame.path.c_str(), decoded_.channels());
  }
  if (out.data != target) {  // would break the caller's slot ownership; never expected
    return fail(ErrorCode::kInvalidArgument, "output buffer was reallocated");
  }
  return {};
}

Expected<FrameInfo> FileFrameSource::next(cv::Mat& out, std::chrono::milliseconds timeout) {
  if (!dataset_) return fail(ErrorCode::kDisconnected, "%s: not open", options_.directory.c_str());
  const auto& frames = dataset_->frames;
  if (next_index_ >= frames.size() && !startOver())
    return fail(ErrorCode::kEndOfStream, "%s: end of dataset", options_.directory.c_str());

  Due due;
  if (options_.realtime) {
    Expected<Due> paced = pace(timeout);
    if (!paced) return std::unexpected(paced.error());
    due = *paced;
  }
  const DatasetFrame& frame = frames[next_index_];

  // Read and check the frame. A missing directory is a disconnect (not consumed), a
  // missing or undecodable file a bad frame (consumed).
  std::error_code ec;
  if (!fs::is_directory(frame.path.parent_path(), ec)) {
    return fail(ErrorCode::kDisconnected, "%s: dataset directory vanished",
                options_.directory.c_str());
  }
  FrameInfo info;
  info.sequence = sequence_++;
  info.index = static_cast<int>(next_index_);
  info.source_timestamp = frame.timestamp;
  info.exposure_s = frame.exposure_s;
  info.resynchronised = due.resynchronised;
  ++next_index_;

  if (Expected<void> read = readFrame(frame.path, options_.frame_size, bytes_, decoded_); !read) {
    if (!fs::is_directory(frame.path.parent_path(), ec)) {  // vanished while reading
      --next_index_;
      --sequence_;
      return fail(ErrorCode::kDisconnected, "%s: dataset directory vanished",
                  options_.directory.c_str());
    }
    return fail(ErrorCode::kBadFrame, "%s", read.error().c_str());
  }
  if (Expected<void> grey = toGrey(frame, out); !grey) return std::unexpected(grey.error());
  info.capture_time_us = options_.realtime ? due.capture_us : wallClockMicros();
  return info;
}

}  // namespace omnipose
