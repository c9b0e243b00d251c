// omnipose-calibrate's frame set: 1-4 small frames through the ring detector and the lens
// calibrator (calibrateLens, the tool's default mode), as tools/calibrate/main.cpp calls them.
// Layout: byte 0 chooses, the rest is the frame data:
//   bits 0-1  frame count - 1 (1..4)
//   bit 2     1: image files, each [u32 length, little-endian][bytes] (a length larger than
//             what is left takes what is left), decoded with cv::imdecode(IMREAD_COLOR) as
//             the tool's cv::imread; a frame larger than 320 x 240 pixels (or either way
//             round) ends the input;
//             0: raw pixel blocks of 128 x 128, frame k starting at byte k * (frame bytes)
//             of the data, the data repeated to fill
//   bit 3     raw: 3-channel BGR instead of grey
//   bit 4     options.turn_left (the frames are a turn to the left: azimuth direction)
//   bit 5     up cue dark instead of bright (outer_edge from the vertical cue)
//   bit 6     also propose a mask (proposeMask, omnipose-calibrate --propose-mask) from >= 3
//             frames
//   bit 7     options.replay (consecutive frames through the Pipeline after calibrating)
// The detector uses 256 rays instead of the tool's 1024 (same code paths, a quarter of the
// work) so that an execution stays well under a second under the sanitizers.
// calibrateLens either throws a std::exception (a clean refusal: no ring, sizes differ ...)
// or returns a calibration that validates and whose yaml() reads back with
// Calibration::parse; its report and preview must render. proposeMask either throws
// std::runtime_error or returns an 8-bit mask of the frame size. A crash or a sanitizer
// report is a finding.
#include <cstdint>
#include <exception>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <vector>

#include "omnipose/calibrate/lens_calibrator.hpp"
#include "omnipose/calibrate/mask_proposal.hpp"
#include "omnipose/calibrate/preview.hpp"
#include "omnipose/calibration.hpp"

namespace {

constexpr int kRawSide = 128;
constexpr int kMaxLong = 320, kMaxShort = 240;

std::vector<cv::Mat> decodeFiles(const std::uint8_t* data, std::size_t size, int count) {
  std::vector<cv::Mat> frames;
  for (int k = 0; k < count && size > 0; ++k) {
    std::size_t n = size;
    if (size >= 4) {
      n = static_cast<std::size_t>(data[0]) | (static_cast<std::size_t>(data[1]) << 8) |
          (static_cast<std::size_t>(data[2]) << 16) | (static_cast<std::size_t>(data[3]) << 24);
      data += 4;
      size -= 4;
      if (n > size) n = size;
    }
    const cv::Mat bytes(1, static_cast<int>(n), CV_8UC1, const_cast<std::uint8_t*>(data));
    data += n;
    size -= n;
    cv::Mat m;
    try {
      m = cv::imdecode(bytes, cv::IMREAD_COLOR);
    } catch (const cv::Exception&) {
      m.release();
    }
    if (m.empty()) continue;  // the tool refuses an unreadable file; the others still go in
    if (std::max(m.cols, m.rows) > kMaxLong || std::min(m.cols, m.rows) > kMaxShort) break;
    frames.push_back(std::move(m));
  }
  return frames;
}

std::vector<cv::Mat> rawBlocks(const std::uint8_t* data, std::size_t size, int count, bool colour) {
  std::vector<cv::Mat> frames;
  for (int k = 0; k < count; ++k) {
    cv::Mat m(kRawSide, kRawSide, colour ? CV_8UC3 : CV_8UC1);
    const std::size_t n = m.total() * m.elemSize();
    for (std::size_t i = 0; i < n; ++i) m.data[i] = data[(k * n + i) % size];
    frames.push_back(std::move(m));
  }
  return frames;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  const std::uint8_t mode = data[0];
  ++data;
  --size;
  const int count = 1 + (mode & 3);
  const std::vector<cv::Mat> frames =
      (mode & 4) ? decodeFiles(data, size, count) : rawBlocks(data, size, count, mode & 8);
  if (frames.empty()) return 0;

  omnipose::calibrate::LensCalibratorOptions options;
  options.detector.rays = 256;
  options.turn_left = (mode & 16) != 0;
  options.replay = (mode & 128) != 0;
  options.up_cue = (mode & 32) ? omnipose::calibrate::UpCue::kDark : omnipose::calibrate::UpCue::kBright;
  try {
    const auto result = omnipose::calibrate::calibrateLens(frames, options);
    if (!result.calibration.validate().empty()) __builtin_trap();
    // What omnipose-calibrate writes must read back.
    const omnipose::Calibration back = omnipose::Calibration::parse(result.yaml(), "calibrated.yaml");
    if (back.omni.image_width != frames.front().cols || back.omni.image_height != frames.front().rows)
      __builtin_trap();
    (void)result.report();
    const auto lines = result.summaryLines();
    const omnipose::calibrate::RingDetection* det = nullptr;
    if (!result.detection_errors.empty() && result.detection_errors.front().empty() &&
        !result.detections.empty())
      det = &result.detections.front();
    const cv::Mat preview = omnipose::calibrate::renderPreview(frames, result.calibration, det, lines);
    if (preview.empty() || preview.type() != CV_8UC3) __builtin_trap();
  } catch (const omnipose::CalibrationError&) {
    __builtin_trap();  // yaml() wrote something parse() refuses
  } catch (const std::exception&) {
  }

  if ((mode & 64) && frames.size() >= 3) {
    try {
      const auto proposal = omnipose::calibrate::proposeMask(frames);
      if (proposal.mask.type() != CV_8UC1 || proposal.mask.size() != frames.front().size())
        __builtin_trap();
    } catch (const std::runtime_error&) {
    }
  }
  return 0;
}
