#pragma once
/// \file bindings.hpp
/// The parts of the module omnipose._omnipose, each adding its classes and functions.

#include <nanobind/nanobind.h>

#include <filesystem>
#include <string>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/odometry.hpp"

namespace omnipose::python {

/// Calibration, ConfigError, read_frame().
void bindCalibration(nanobind::module_& m);
/// FrameResult (what Odometry.process returns).
void bindResult(nanobind::module_& m);
/// Odometry.
void bindOdometry(nanobind::module_& m);
/// replay(), open_dataset().
void bindReplay(nanobind::module_& m);
/// Panorama, encode_jpeg().
void bindPanorama(nanobind::module_& m);

/// The odometry options that daemon.yaml text `options_yaml` (its pipeline, keyframes,
/// plausibility and input keys; src/python/omnipose/__init__.py writes it from keyword arguments)
/// gives, read by the daemon's own parser (DaemonConfig::parse, then checkAgainst the
/// calibration) so names, ranges and messages are the daemon's; relative paths are relative
/// to `base_dir` (empty: the current directory). Throws ConfigError listing every problem,
/// each starting with `origin` and the key; `warnings` receives the parser's warnings
/// (threads clamped).
OdometryOptions parseOdometryOptions(const std::string& options_yaml, const std::string& origin,
                                     const Calibration& calibration,
                                     std::vector<std::string>& warnings,
                                     const std::filesystem::path& base_dir = {});

}  // namespace omnipose::python
