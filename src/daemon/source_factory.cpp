#include "daemon/source_factory.hpp"

#include <stdexcept>
#include <string>
#include <vector>

#include "daemon/file_frame_source.hpp"
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

/// Every problem of the source section at once (the driver's own checks).
void throwIfInvalid(const std::vector<std::string>& problems) {
  if (problems.empty()) return;
  std::string text = "invalid source configuration:";
  for (const auto& p : problems) text += "\n  " + p;
  throw std::runtime_error(text);
}

}  // namespace

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
      throwIfInvalid(V4l2Source::validate(config));
      return std::make_unique<V4l2Source>(config);
    case SourceConfig::Type::kLibcamera:
#if defined(OMNIPOSE_HAVE_LIBCAMERA)
      throwIfInvalid(LibcameraSource::validate(config));
      return std::make_unique<LibcameraSource>(config);
#else
      break;
#endif
  }
  throw std::runtime_error(std::string("source.type: '") + toString(config.type) +
                           "' is not built into this daemon (available: " + kAvailable +
                           "; the libcamera source needs libcamera-dev at build time)");
}

}  // namespace omnipose::daemon
