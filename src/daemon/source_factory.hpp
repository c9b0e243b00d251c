#pragma once
/// \file source_factory.hpp
/// The one place that turns `source:` of daemon.yaml into a FrameSource. New drivers
/// (v4l2, libcamera) plug in here.

#include <filesystem>
#include <memory>
#include <opencv2/core.hpp>

#include "omnipose/config.hpp"
#include "omnipose/frame_source.hpp"

namespace omnipose::daemon {

/// What a source needs to know beyond its own configuration section.
struct SourceContext {
  /// Frame size the pipeline expects (the omni image or the panorama, by `input`), pixels.
  cv::Size frame_size;
  /// The daemon's calibration file (a file source uses it instead of DATASET/calibration.yaml).
  std::filesystem::path calibration;
};

/// Creates (does not open) the source. Throws std::runtime_error naming `source.type` when
/// that kind of source is not built into this daemon.
std::unique_ptr<FrameSource> makeFrameSource(const SourceConfig& config,
                                             const SourceContext& context);

}  // namespace omnipose::daemon
