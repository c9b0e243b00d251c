#pragma once
/// \file source_factory.hpp
/// The one place that turns `source:` of daemon.yaml into a FrameSource, and the one place
/// where its keys become each driver's own options (FileFrameSource::Options, V4l2Options,
/// LibcameraOptions). New drivers plug in here.

#include <filesystem>
#include <memory>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "daemon/config.hpp"
#include "omnipose/calibration.hpp"
#include "omnipose/frame_source.hpp"

namespace omnipose {
// The drivers' options (drivers/v4l2/v4l2_source.hpp, drivers/libcamera/libcamera_source.hpp);
// callers of the mapping functions below include those headers.
struct V4l2Options;
struct LibcameraOptions;
}  // namespace omnipose

namespace omnipose::daemon {

/// What a source needs to know beyond its own configuration section.
struct SourceContext {
  /// Frame size the pipeline expects (the omni image or the panorama, by `input`), pixels.
  cv::Size frame_size;
  /// The daemon's calibration file (a file source uses it instead of DATASET/calibration.yaml).
  std::filesystem::path calibration;
  /// Its sensor timing: a V4L2 source dates end-of-frame timestamps back by the readout, a
  /// libcamera source moves each stamp to the first row's capture time (`stamped_at`, the
  /// frame's reported exposure, else `exposure_s`).
  SensorTiming sensor;
};

/// source.device, .width, .height, .fps, .format as V4l2Options (tuning left at its
/// defaults). Pure.
V4l2Options v4l2Options(const SourceConfig& config);
/// source.camera, .width, .height, .fps, .format as LibcameraOptions (tuning left at its
/// defaults). Pure. Defined only when the daemon is built with the libcamera source
/// (OMNIPOSE_HAVE_LIBCAMERA).
LibcameraOptions libcameraOptions(const SourceConfig& config);

/// Every problem of the source section's driver options, without opening anything (for
/// `omniposed --check`): the camera driver's validate() of the mapped options, each message
/// naming its daemon.yaml key ("source.fps: ..."); a source type not built into this
/// daemon is a "source.type: ..." problem. A file source has no driver options to check
/// here (its directory is checked by checkStartup()): empty.
std::vector<std::string> checkSourceOptions(const SourceConfig& config);

/// Creates (does not open) the source. Throws std::runtime_error listing every problem of
/// checkSourceOptions(), which includes `source.type` when that kind of source is not built
/// into this daemon.
std::unique_ptr<FrameSource> makeFrameSource(const SourceConfig& config,
                                             const SourceContext& context);

}  // namespace omnipose::daemon
