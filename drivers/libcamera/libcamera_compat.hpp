#pragma once
/// \file libcamera_compat.hpp
/// The libcamera API differences between Debian 12's 0.0.3 and later releases that the
/// source touches, behind <libcamera/version.h>.
///
/// - 0.1.0 removed the StreamRoles alias; generateConfiguration() takes a
///   Span<const StreamRole> instead of a const std::vector<StreamRole>&.
/// - ControlList::get() returns std::optional<T> from 0.0.1 on (older returned T); 0.0.3
///   is the oldest version supported here, so it is always optional.

#include <libcamera/camera.h>
#include <libcamera/stream.h>
#include <libcamera/version.h>

#include <array>
#include <memory>

#define OMNIPOSE_LIBCAMERA_VERSION_AT_LEAST(major, minor, patch)                       \
  ((LIBCAMERA_VERSION_MAJOR > (major)) ||                                                \
   (LIBCAMERA_VERSION_MAJOR == (major) && LIBCAMERA_VERSION_MINOR > (minor)) ||          \
   (LIBCAMERA_VERSION_MAJOR == (major) && LIBCAMERA_VERSION_MINOR == (minor) &&          \
    LIBCAMERA_VERSION_PATCH >= (patch)))

#if !OMNIPOSE_LIBCAMERA_VERSION_AT_LEAST(0, 0, 1)
#error "omnipose's libcamera source needs libcamera >= 0.0.1 (ControlList::get returning optional)"
#endif

namespace omnipose::libcam {

/// One stream of the given role.
inline std::unique_ptr<libcamera::CameraConfiguration> generateOneStreamConfiguration(
    libcamera::Camera& camera, libcamera::StreamRole role) {
#if OMNIPOSE_LIBCAMERA_VERSION_AT_LEAST(0, 1, 0)
  const std::array<libcamera::StreamRole, 1> roles{role};
  return camera.generateConfiguration(roles);
#else
  const libcamera::StreamRoles roles{role};
  return camera.generateConfiguration(roles);
#endif
}

}  // namespace omnipose::libcam
