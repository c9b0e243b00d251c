#pragma once
/// \file dataset.hpp
/// A recorded or rendered dataset directory (DESIGN.md section 6):
///   DATASET/calibration.yaml   lens and panorama
///   DATASET/frames/            images sorted by name: png, jpg, jpeg, pgm, ppm, bmp
///   DATASET/timestamps.txt     optional "<file name> <seconds> [<exposure seconds>]" per
///                              line; else i / 30 s
///   DATASET/groundtruth.tum    optional camera poses (TUM)

#include <cstdint>
#include <filesystem>
#include <limits>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/error.hpp"
#include "omnipose/io/trajectory.hpp"

namespace omnipose {

struct DatasetFrame {
  std::filesystem::path path;
  /// Seconds: the first row's capture time, the recorded stamp moved by the calibration's
  /// sensor.timestamp (SensorTiming::captureTimeOffset()) when it is not the middle of the
  /// exposure.
  double timestamp = 0.0;
  /// The frame's exposure as recorded (timestamps.txt's third column), seconds; NaN: not
  /// recorded (FrameStamp::exposure_s).
  double exposure_s = std::numeric_limits<double>::quiet_NaN();
};

struct Dataset {
  /// Frame rate assumed when there is no timestamps.txt.
  static constexpr double kDefaultFps = 30.0;

  std::filesystem::path root;
  Calibration calibration;
  std::vector<DatasetFrame> frames;
  std::optional<std::vector<StampedPose>> groundtruth;
  /// DATASET/imu.csv when there is one (the robot's gyro; read it with readGyroCsv()).
  std::optional<std::filesystem::path> gyro_file;
  /// false: no timestamps.txt, the frames were stamped i / kDefaultFps.
  bool timestamps_from_file = false;
  /// What timestamps.txt says that a user should know, each naming its line: a negative
  /// time, a frame not after the one before it (the pipeline starts a new segment there).
  /// At most 20, then one line counting the rest.
  std::vector<std::string> warnings;

  /// A warning for the user when something the calibration needs had to be assumed: a
  /// rolling shutter (sensor.readout_s) with frame times that are not recorded. Empty when
  /// nothing was assumed.
  std::string assumptions() const;

  /// Opens `root`. `calibration_override` replaces DATASET/calibration.yaml when given.
  /// Throws std::runtime_error naming the path on: missing directory, missing frames/
  /// folder or no images in it, missing/invalid calibration (CalibrationError), a
  /// timestamps.txt or groundtruth.tum that is not a regular file or is larger than
  /// kMaxTextFileBytes (file_io.hpp), a malformed timestamps.txt line (a value that is not
  /// a plain decimal within +-1e10 s, an exposure outside [0, 10] s, a file name given
  /// twice: the line is named), or a
  /// frame without a timestamp.
  static Dataset open(const std::filesystem::path& root,
                      const std::optional<std::filesystem::path>& calibration_override = {});
};

/// True for the image file endings a dataset may use (case-insensitive).
bool isImageFile(const std::filesystem::path& path);

/// Reads one 8-bit frame as stored (grey stays grey, colour stays BGR) through
/// decodeImage() (image_decode.hpp): the header's size is checked before any pixel is
/// decoded. `expected_size`, when not empty, is the only size accepted (the calibration's
/// frame size). kNotFound when the file is missing, kBadFrame naming the file for every
/// other problem (not an image, corrupt, truncated, wrong or oversized declared size, not
/// 8-bit), kIoError when reading fails. Never throws.
Expected<cv::Mat> readFrame(const std::filesystem::path& path, cv::Size expected_size = {});

/// readFrame() into `out`, reusing `buffer` for the file's bytes and `out` when its size and
/// type already match (a replay's steady state decodes without new buffers).
Expected<void> readFrame(const std::filesystem::path& path, cv::Size expected_size,
                         std::vector<std::uint8_t>& buffer, cv::Mat& out);

}  // namespace omnipose
