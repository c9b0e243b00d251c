#pragma once
/// \file dataset_writer.hpp
/// Writes rendered frames with their timestamps and ground truth as a dataset directory.

#include <cstddef>
#include <filesystem>
#include <limits>
#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/gyro.hpp"
#include "omnipose/io/trajectory.hpp"

namespace omnipose::synth {

/// Writes a dataset directory (DESIGN.md section 6):
/// ```
///   DIR/calibration.yaml   DIR/frames/000000.png (or .jpg)   DIR/timestamps.txt
///   DIR/groundtruth.tum    (camera poses relative to the first frame, so it is the identity)
///   DIR/imu.csv            (optional: writeGyro())
/// ```
class DatasetWriter {
 public:
  /// Creates DIR and DIR/frames and writes calibration.yaml. `jpeg_quality` 1..100 writes
  /// JPEG frames of that quality, 0 lossless PNG. Throws std::runtime_error naming the path
  /// when a directory cannot be created or written, or when DIR/frames is not empty
  /// (stale frames of an older run would be replayed).
  DatasetWriter(std::filesystem::path directory, const Calibration& calibration,
                int jpeg_quality = 0);

  /// Writes the next frame (CV_8UC1) with its timestamp and ground-truth pose
  /// T_world_camera, and the exposure its camera reports (seconds, timestamps.txt's third
  /// column; NaN: none). Throws std::runtime_error naming the file when it cannot be written.
  void addFrame(const cv::Mat& image, const StampedPose& pose,
                double exposure_s = std::numeric_limits<double>::quiet_NaN());
  /// Writes the gyro's samples as DIR/imu.csv (io/gyro.hpp). Throws std::runtime_error
  /// naming the file when it cannot be written.
  void writeGyro(std::span<const GyroSample> samples);
  /// Writes timestamps.txt and groundtruth.tum. Throws std::runtime_error naming the file.
  void finish();

  /// File name (no directory) of frame number i, e.g. "000007.png".
  std::string frameName(std::size_t i) const;
  const std::filesystem::path& directory() const { return directory_; }

 private:
  std::filesystem::path directory_;
  int jpeg_quality_;
  std::vector<StampedPose> poses_;
  std::vector<double> exposures_;  ///< per frame, seconds; NaN: none stated
};

}  // namespace omnipose::synth
