#pragma once
/// \file libcamera_formats.hpp
/// The parts of the libcamera source that need no camera and no libcamera headers, so they
/// are unit-tested on their own: which pixel formats become grey and how, the choice of a
/// format among those a camera offers, the choice of a camera by index or id (and, in
/// libcamera_formats.cpp, validate(const LibcameraOptions&)). Pixel formats are DRM
/// fourccs, as libcamera's formats::R8.fourcc() etc.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "omnipose/error.hpp"

namespace omnipose::libcam {

/// A little-endian fourcc, as libcamera (DRM) spells formats.
constexpr std::uint32_t fourcc(char a, char b, char c, char d) {
  return static_cast<std::uint32_t>(static_cast<unsigned char>(a)) |
         static_cast<std::uint32_t>(static_cast<unsigned char>(b)) << 8 |
         static_cast<std::uint32_t>(static_cast<unsigned char>(c)) << 16 |
         static_cast<std::uint32_t>(static_cast<unsigned char>(d)) << 24;
}

/// How a buffer of a format becomes 8-bit grey.
enum class GreyConversion {
  kLumaPlane,    ///< plane 0 is 8-bit luma (R8, NV12, YUV420, ...): copy rows
  kPackedLuma0,  ///< packed 4:2:2 with luma first (YUYV, YVYU)
  kPackedLuma1,  ///< packed 4:2:2 with chroma first (UYVY, VYUY)
  kJpeg,         ///< MJPEG: decode (allocates)
};

struct GreyFormat {
  std::uint32_t fourcc;
  const char* name;  ///< libcamera's name ("R8", "NV12", "YUYV", "MJPEG", ...)
  GreyConversion conversion;
};

/// Every grey-convertible format, best first (no conversion, then a luma plane to copy,
/// then packed 4:2:2, then JPEG to decode).
std::span<const GreyFormat> greyFormats();

/// The entry for a fourcc, or nullptr when it cannot be turned into grey.
const GreyFormat* findGreyFormat(std::uint32_t fourcc);

/// A configured format name: libcamera's names (R8, NV12, NV21, YUV420, YVU420, NV16, NV61,
/// YUV422, YUYV, YVYU, UYVY, VYUY, MJPEG) and the V4L2 spellings GREY / Y8 / MJPG,
/// case-insensitive. "" and "auto" mean "the best the camera offers" (returns 0).
/// nullopt: not a grey-convertible format name.
std::optional<std::uint32_t> parseFormatName(std::string_view name);

/// "R8", "YUYV", ... or the fourcc's four characters.
std::string formatName(std::uint32_t fourcc);

struct FormatChoice {
  std::uint32_t fourcc = 0;
  bool substituted = false;  ///< the requested format is not offered; `fourcc` replaces it
};

/// The format to configure: the requested one when the camera offers it, else (or for
/// "auto") the best grey-convertible one offered. Errors: kInvalidArgument (an unknown
/// name), kUnsupportedFormat (nothing offered converts to grey; the message lists the
/// offers).
Expected<FormatChoice> chooseFormat(std::string_view requested,
                                    std::span<const std::uint32_t> offered);

/// `camera:` is an index ("0", "1", ...) or a libcamera camera id
/// ("/base/soc/i2c0mux/i2c@1/imx219@10", "\_SB_.PCI0.XHC_.RHUB.HS05-5:1.0-0c45:6366").
struct CameraSelector {
  std::optional<std::size_t> index;
  std::string id;
};
CameraSelector parseCameraSelector(std::string_view camera);

/// The position in `ids` (the cameras libcamera found, in its order) of the selected one.
/// Errors: kNoDevice "no camera" when `ids` is empty, kNoDevice for an index out of range,
/// kNotFound for an unknown id; messages list the cameras present.
Expected<std::size_t> selectCamera(const CameraSelector& selector,
                                   std::span<const std::string> ids);

/// Frame duration limits for a frame rate: {min, max} in microseconds, both 1e6 / fps
/// rounded; fps must be > 0.
std::int64_t frameDurationUs(double fps);

}  // namespace omnipose::libcam
