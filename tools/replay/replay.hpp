#pragma once
// Headless replay of a dataset directory through a motion estimator.

#include <cstdio>
#include <filesystem>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "daemon/config.hpp"
#include "omnipose/io/dataset.hpp"
#include "omnipose/io/replay.hpp"
#include "omnipose/motion_estimator.hpp"
#include "omnipose/odometry.hpp"

namespace omnipose::replay {

struct ReplayOptions {
  std::filesystem::path dataset;
  std::optional<std::filesystem::path> out_tum;           ///< the map pose
  std::optional<std::filesystem::path> out_odometry_tum;  ///< the odometry's pose
  std::optional<std::filesystem::path> relative_csv;
  std::optional<std::filesystem::path> config;
  std::optional<std::filesystem::path> calibration;
  std::optional<InputKind> input;  ///< overrides the config's input
  std::string method = "ifmi";
  bool progress = true;
  /// The first frame replayed (dataset order): a run that starts part of the way in; and
  /// at most this many frames from it (0: to the end).
  int from = 0;
  int count = 0;
  /// A map (src/map/map_file.hpp) loaded before the first frame: the frames relocalise in it
  /// (Odometry::restoreMap()); one that cannot be used is an error naming it.
  std::optional<std::filesystem::path> map_in;
  /// Where the map is saved after the last frame.
  std::optional<std::filesystem::path> map_out;
};

struct ReplaySummary : ReplayCounts {
  /// frames whose rows' rotations within the frame came from the dataset's gyro (imu.csv)
  int gyro_frames = 0;
  double median_seconds_per_frame = 0.0;
  int loops_closed = 0;  ///< frames that closed a loop (OdometryResult::loop_closed)
  int places = 0;        ///< places in the odometry's memory at the end
  /// With map_in: the frame (dataset index) on which the loaded map was found; -1 if never.
  int relocalised_at = -1;
};

/// Builds the estimator for `method`. Throws std::invalid_argument for an unknown name
/// (the message lists the known ones).
std::unique_ptr<MotionEstimator> makeEstimator(const std::string& method,
                                               const Calibration& calibration,
                                               const PipelineOptions& options);
/// The frame-to-pose policy for `method`: the iFMI odometry with keyframes, or a feature
/// method's pairs chained by the same policy. Throws as makeEstimator.
std::unique_ptr<Odometry> makeOdometry(const std::string& method, const Calibration& calibration,
                                       const OdometryOptions& options);
/// Names makeEstimator accepts.
std::vector<std::string> methodNames();

/// Runs the replay, writes the outputs, reports skipped frames on `log`.
ReplaySummary run(const ReplayOptions& options, std::FILE* log);

}  // namespace omnipose::replay
