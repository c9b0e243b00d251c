#pragma once
/// \file replay.hpp
/// A recorded dataset through the odometry, frame by frame, as omnipose-replay and the
/// Python package's replay() run it: one loop, so both count, skip and log alike.

#include <functional>
#include <span>
#include <string>
#include <vector>

#include "omnipose/gyro.hpp"
#include "omnipose/io/dataset.hpp"
#include "omnipose/io/trajectory.hpp"
#include "omnipose/odometry.hpp"
#include "omnipose/unwrapper.hpp"

namespace omnipose {

/// What a replay did with the dataset's frames.
struct ReplayCounts {
  int frames = 0;       ///< frames in the dataset
  int pairs = 0;        ///< relative poses estimated (tracked or bridged)
  int skipped = 0;      ///< unreadable / wrong-size / black frames, and the implausible ones
  int implausible = 0;  ///< of the skipped: decoded but not believed (PlausibilityOptions)
  int lost = 0;         ///< fits that failed and could not be bridged (a new segment)
  int bridged = 0;      ///< pairs found again across a gap or a lost fit (in pairs)
};

/// Called for every frame the odometry took (any state, kLost included), in order, with the
/// frame's index in the dataset.
using ReplayObserver =
    std::function<void(int index, const DatasetFrame& frame, const OdometryResult& result)>;
/// Called with each line a user should read: "skipped PATH: why", "lost PATH: ...".
using ReplayLog = std::function<void(const std::string& line)>;

/// The dataset's gyro samples (imu.csv) when its calibration joins them to the frames (its
/// imu section); empty without imu.csv, and empty with `warning` set when the calibration
/// cannot use it. Throws std::runtime_error naming the file when imu.csv is malformed
/// (io/gyro.hpp).
std::vector<GyroSample> datasetGyroSamples(const Dataset& dataset, std::string& warning);

/// Every frame of `dataset` in order through `odometry`: read at the size `input` expects
/// (the calibration's omni frame or panorama), the gyro samples `gyro` (datasetGyroSamples(),
/// or empty) given as a live stream would have delivered them, then processed. A frame that
/// cannot be read is skipped, counted and logged, and the odometry told of the gap; one the
/// odometry refuses (black, implausible) is skipped, counted and logged; a lost fit is
/// counted and logged. `trajectory` gets the map pose (OdometryResult::map_pose: the chained
/// pose corrected by the loop closures so far) of every frame that has one (segment starts,
/// tracked and bridged frames), stamped with the frame's timestamp; the observer sees the
/// odometry's own pose (OdometryResult::pose).
ReplayCounts replayDataset(const Dataset& dataset, Odometry& odometry,
                           std::span<const GyroSample> gyro, InputKind input,
                           std::vector<StampedPose>& trajectory, const ReplayObserver& observe,
                           const ReplayLog& log);

}  // namespace omnipose
