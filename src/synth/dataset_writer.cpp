#include <cmath>
#include <cstdio>
#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "omnipose/io/gyro.hpp"
#include "omnipose/synth/dataset_writer.hpp"

namespace omnipose::synth {

DatasetWriter::DatasetWriter(std::filesystem::path directory, const Calibration& calibration,
                             int jpeg_quality)
    : directory_(std::move(directory)), jpeg_quality_(jpeg_quality) {
  if (jpeg_quality_ < 0 || jpeg_quality_ > 100) {
    throw std::invalid_argument("DatasetWriter: jpeg_quality must be in [0, 100] (0 = PNG)");
  }
  const std::filesystem::path frames = directory_ / "frames";
  std::error_code ec;
  std::filesystem::create_directories(frames, ec);
  if (ec) throw std::runtime_error(frames.string() + ": cannot create directory: " + ec.message());
  if (!std::filesystem::is_empty(frames, ec) || ec) {
    throw std::runtime_error(frames.string() +
                             ": not empty; write the dataset into a new directory");
  }
  calibration.save(directory_ / "calibration.yaml");
}

std::string DatasetWriter::frameName(std::size_t i) const {
  char name[32];
  std::snprintf(name, sizeof(name), "%06zu.%s", i, jpeg_quality_ > 0 ? "jpg" : "png");
  return name;
}

void DatasetWriter::addFrame(const cv::Mat& image, const StampedPose& pose, double exposure_s) {
  const std::filesystem::path path = directory_ / "frames" / frameName(poses_.size());
  if (image.empty() || image.type() != CV_8UC1) {
    throw std::invalid_argument(path.string() + ": frame must be a non-empty CV_8UC1 image");
  }
  const std::vector<int> params =
      jpeg_quality_ > 0 ? std::vector<int>{cv::IMWRITE_JPEG_QUALITY, jpeg_quality_}
                        : std::vector<int>{cv::IMWRITE_PNG_COMPRESSION, 3};
  bool ok = false;
  try {
    ok = cv::imwrite(path.string(), image, params);
  } catch (const cv::Exception& e) {
    throw std::runtime_error(path.string() + ": cannot write frame: " + e.what());
  }
  if (!ok) throw std::runtime_error(path.string() + ": cannot write frame");
  poses_.push_back(pose);
  exposures_.push_back(exposure_s);
}

void DatasetWriter::writeGyro(std::span<const GyroSample> samples) {
  writeGyroCsv(directory_ / "imu.csv", samples);
}

void DatasetWriter::finish() {
  const std::filesystem::path stamps = directory_ / "timestamps.txt";
  std::ofstream out(stamps);
  char seconds[64];
  for (std::size_t i = 0; i < poses_.size(); ++i) {
    std::snprintf(seconds, sizeof(seconds), "%.6f", poses_[i].timestamp);
    out << frameName(i) << ' ' << seconds;
    if (std::isfinite(exposures_[i])) {
      std::snprintf(seconds, sizeof(seconds), "%.9g", exposures_[i]);
      out << ' ' << seconds;
    }
    out << '\n';
  }
  if (!out) throw std::runtime_error(stamps.string() + ": cannot write timestamps");
  // Ground truth relative to the first frame: T_0^-1 * T_k, so the first pose is identity.
  std::vector<StampedPose> relative = poses_;
  if (!poses_.empty()) {
    const Eigen::Isometry3d first_inverse = poses_.front().pose.inverse();
    for (auto& p : relative) p.pose = first_inverse * p.pose;
  }
  writeTum(directory_ / "groundtruth.tum", relative);
}

}  // namespace omnipose::synth
