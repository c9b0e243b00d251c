#include "daemon/source_factory.hpp"

#include <stdexcept>
#include <string>
#include <vector>

#include "file/file_frame_source.hpp"
#include "v4l2/v4l2_source.hpp"
#if defined(OMNIPOSE_HAVE_LIBCAMERA)
#include "libcamera/libcamera_source.hpp"
#endif

namespace omnipose::daemon {
namespace {

#if defined(OMNIPOSE_HAVE_LIBCAMERA)
constexpr const char* kAvailable = "file, v4l2, libcamera";
#else
constexpr const char* kAvailable = "file, v4l2";
#endif

std::string notBuiltIn(SourceConfig::Type type) {
  return std::string("source.type: '") + toString(type) +
         "' is not built into this daemon (available: " + kAvailable +
         "; the libcamera source needs libcamera-dev at build time)";
}

/// Every problem of the source section at once (the driver's own checks).
void throwIfInvalid(const std::vector<std::string>& problems) {
  if (problems.empty()) return;
  std::string text = "invalid source configuration:";
  for (const auto& p : problems) text += "\n  " + p;
  throw std::runtime_error(text);
}

/// The stream settings the cameras share (size, rate, pixel format), from the source section.
template <typename CameraOptions>
CameraOptions withStreamSettings(const SourceConfig& config, CameraOptions o) {
  o.width = config.width;
  o.height = config.height;
  o.fps = config.fps;
  o.format = config.format;
  return o;
}

}  // namespace

V4l2Options v4l2Options(const SourceConfig& config) {
  V4l2Options o;
  o.device = config.device;
  return withStreamSettings(config, o);
}

#if defined(OMNIPOSE_HAVE_LIBCAMERA)
LibcameraOptions libcameraOptions(const SourceConfig& config) {
  LibcameraOptions o;
  o.camera = config.camera;
  return withStreamSettings(config, o);
}
#endif

std::vector<std::string> checkSourceOptions(const SourceConfig& config) {
  switch (config.type) {
    case SourceConfig::Type::kFile: return {};
    case SourceConfig::Type::kV4l2: return validate(v4l2Options(config));
    case SourceConfig::Type::kLibcamera:
#if defined(OMNIPOSE_HAVE_LIBCAMERA)
      return validate(libcameraOptions(config));
#else
      break;
#endif
  }
  return {notBuiltIn(config.type)};
}

std::unique_ptr<FrameSource> makeFrameSource(const SourceConfig& config,
                                             const SourceContext& context) {
  switch (config.type) {
    case SourceConfig::Type::kFile:
      return std::make_unique<FileFrameSource>(FileFrameSource::Options{
          .directory = config.path,
          .calibration = context.calibration,
          .frame_size = context.frame_size,
          .realtime = config.realtime,
          .loop = config.loop,
      });
    case SourceConfig::Type::kV4l2:
      throwIfInvalid(checkSourceOptions(config));
      {
        V4l2Options options = v4l2Options(config);
        options.readout_s = context.sensor.readout_s;
        return std::make_unique<V4l2Source>(options);
      }
    case SourceConfig::Type::kLibcamera:
#if defined(OMNIPOSE_HAVE_LIBCAMERA)
      throwIfInvalid(checkSourceOptions(config));
      {
        LibcameraOptions options = libcameraOptions(config);
        options.sensor = context.sensor;
        return std::make_unique<LibcameraSource>(options);
      }
#else
      break;
#endif
  }
  throw std::runtime_error(notBuiltIn(config.type));
}

}  // namespace omnipose::daemon
