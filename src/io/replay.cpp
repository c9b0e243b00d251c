#include "omnipose/io/replay.hpp"

#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>

#include "omnipose/io/gyro.hpp"

namespace omnipose {

std::vector<GyroSample> datasetGyroSamples(const Dataset& dataset, std::string& warning) {
  warning.clear();
  if (!dataset.gyro_file) return {};
  if (!dataset.calibration.imu) {
    warning = dataset.gyro_file->string() +
              " is not used: the calibration has no imu section (measure it with "
              "omnipose-calibrate --imu-from)";
    return {};
  }
  return readGyroCsv(*dataset.gyro_file).samples;
}

ReplayCounts replayDataset(const Dataset& dataset, Odometry& odometry,
                           std::span<const GyroSample> gyro, InputKind input,
                           std::vector<StampedPose>& trajectory, const ReplayObserver& observe,
                           const ReplayLog& log) {
  const Calibration& calibration = dataset.calibration;
  const cv::Size frame_size = inputFrameSize(calibration, input);
  ReplayCounts counts;
  counts.frames = static_cast<int>(dataset.frames.size());
  std::vector<std::uint8_t> buffer;
  cv::Mat image;
  for (int i = 0; i < counts.frames; ++i) {
    const DatasetFrame& f = dataset.frames[i];
    if (auto read = readFrame(f.path, frame_size, buffer, image); !read) {
      odometry.markGap();
      ++counts.skipped;
      log("skipped " + f.path.string() + ": " + read.error().c_str());
      continue;
    }
    if (!gyro.empty() && calibration.imu) {
      const SensorTiming& sensor = calibration.sensor;
      const std::size_t n = gyroSamplesArrivedBy(
          gyro, *calibration.imu, sensor.exposureEndAfterStamp(sensor.exposureOf(f.exposure_s)),
          f.timestamp);
      odometry.addGyro(gyro.first(n));
      gyro = gyro.subspan(n);
    }
    const Expected<OdometryResult> result = odometry.process(
        image, {.time_s = f.timestamp, .sequence = i, .exposure_s = f.exposure_s});
    if (!result) {
      ++counts.skipped;
      if (result.error().code() == ErrorCode::kImplausible) ++counts.implausible;
      log("skipped " + f.path.string() + ": " + result.error().c_str());
      continue;
    }
    switch (result->state) {
      case TrackState::kLost:
        ++counts.lost;
        log("lost " + f.path.string() + ": fit failed, starting a new chain segment");
        break;  // no pose: the link across the gap is unknown
      case TrackState::kGyroBridged:
      case TrackState::kBridged:
        ++counts.bridged;
        [[fallthrough]];
      case TrackState::kTracked:
        ++counts.pairs;
        [[fallthrough]];
      case TrackState::kSegmentStart:
        trajectory.push_back({f.timestamp, result->map_pose});
        break;
    }
    if (observe) observe(i, f, *result);
  }
  return counts;
}

}  // namespace omnipose
