#pragma once
/// \file file_frame_source.hpp
/// A FrameSource that replays a dataset directory (DESIGN.md section 6) as if it were a
/// camera: frames in name order, converted to 8-bit grey, stamped on the wall clock.
///
/// Pacing: `realtime` delivers frame i at origin + (t_i - t_0) on the wall clock (t from
/// timestamps.txt, else i / 30 s) and stamps it with that due time; a frame stamped more than
/// `max_pacing_gap_s` after its predecessor is not waited for: pacing restarts from it (it
/// is due at once) and its FrameInfo says `resynchronised`; when the caller is late
/// (busy for more than a frame interval) the frames whose successor is already due are
/// passed over unread, as a camera overwrites frames nobody dequeued, and the sequence
/// number jumps over them (so the recorded timeline is kept); otherwise frames are
/// read as soon as next() is called and stamped with the wall time of reading. `loop`
/// starts again at the first frame after the last (the sequence number keeps counting, the
/// dataset index restarts at 0, the pacing continues one mean frame interval later).
///
/// open() also fails (kUnsupportedFormat) when the first frame declares another size
/// than `frame_size`, so a wrong `input:` or calibration fails at start-up, not per frame.
///
/// Faults (errors as values, never exceptions, DESIGN.md section 5):
///  - a frame that cannot be decoded, is missing, is not 8-bit, or has another size than
///    `frame_size`: kBadFrame naming the file; that frame is consumed (the next call goes
///    on with the next one);
///  - the directory (or its frames/ folder) vanished: kDisconnected naming it; the frame is
///    not consumed, so after close() + open() (which re-lists the directory) replay resumes
///    at the same index with the pacing re-based at that moment;
///  - past the last frame without `loop`: kEndOfStream.
///
/// Allocation: next() decodes an image file, which allocates inside OpenCV and the codec
/// (libpng, libjpeg); the conversion into the caller's buffer does not. The file source is
/// for replay and tests; camera sources are the allocation-free ones.
///
/// Threading: driven by one thread (the capture thread).

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <opencv2/core.hpp>
#include <optional>
#include <string>

#include "omnipose/frame_source.hpp"
#include "omnipose/io/dataset.hpp"

namespace omnipose {

class FileFrameSource final : public FrameSource {
 public:
  struct Options {
    std::filesystem::path directory;    ///< the dataset directory
    std::filesystem::path calibration;  ///< calibration override (empty: DIR/calibration.yaml)
    cv::Size frame_size;                ///< size every frame must have, pixels
    bool realtime = true;               ///< pace by the recorded timestamps
    bool loop = false;                  ///< start again after the last frame
    /// Longest wait between two consecutive recorded frames that realtime pacing honours,
    /// seconds; a longer gap in timestamps.txt is resynchronised instead.
    double max_pacing_gap_s = 10.0;
  };

  explicit FileFrameSource(Options options);

  /// Lists the directory (Dataset::open). kNotFound when it does not exist, kIoError for
  /// any other problem (no frames/, bad timestamps.txt, ...), kUnsupportedFormat for frames
  /// of the wrong size; the message names the path.
  Expected<void> open() override;
  cv::Size frameSize() const override { return options_.frame_size; }
  Expected<FrameInfo> next(cv::Mat& out, std::chrono::milliseconds timeout) override;
  void close() override;
  std::string describe() const override;
  /// The dataset's timestamp warnings (Dataset::warnings).
  std::vector<std::string> warnings() const override;

  /// The sequence number next() gives the next frame it reads (frames it passes over while
  /// catching up with realtime pacing count as lost).
  std::optional<std::uint64_t> sequenceOrigin() const override { return sequence_; }

  /// Frames listed by the last successful open(); 0 before.
  int frameCount() const;

 private:
  /// When the pacing lets the next frame go: its capture time (the wall clock's time it is
  /// due at) and whether pacing started again from it.
  struct Due {
    std::int64_t capture_us = 0;
    bool resynchronised = false;
  };
  /// After the last frame: with loop, frame 0 again one mean frame interval later (true);
  /// false without loop.
  bool startOver();
  /// Realtime pacing: waits for the next frame's due time, at most `timeout` (kTimeout
  /// when it is not due by then); skips the frames missed while the reader was late.
  Expected<Due> pace(std::chrono::milliseconds timeout);
  /// The decoded frame, as 8-bit grey, into `out` (which must be the frame size, CV_8UC1,
  /// and is not reallocated).
  Expected<void> toGrey(const DatasetFrame& frame, cv::Mat& out) const;

  Options options_;
  std::optional<Dataset> dataset_;
  std::size_t next_index_ = 0;   ///< dataset index of the next frame
  std::uint64_t sequence_ = 0;   ///< frames consumed so far (delivered or bad)
  bool has_origin_ = false;      ///< pacing origin set (first next() after open)
  std::int64_t origin_wall_us_ = 0;
  double origin_stamp_ = 0.0;    ///< recorded timestamp that maps to origin_wall_us_
  cv::Mat decoded_;              ///< decoder output, reused when the size does not change
  std::vector<std::uint8_t> bytes_;  ///< the file being decoded, reused frame to frame
};

}  // namespace omnipose
