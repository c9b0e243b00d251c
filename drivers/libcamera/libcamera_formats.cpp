#include "libcamera/libcamera_formats.hpp"

#include <algorithm>
#include <cctype>
#include <cmath>

#include "common/streaming.hpp"
#include "libcamera/libcamera_source.hpp"

namespace omnipose::libcam {
namespace {

constexpr GreyFormat kGreyFormats[] = {
    {fourcc('R', '8', ' ', ' '), "R8", GreyConversion::kLumaPlane},
    {fourcc('N', 'V', '1', '2'), "NV12", GreyConversion::kLumaPlane},
    {fourcc('Y', 'U', '1', '2'), "YUV420", GreyConversion::kLumaPlane},
    {fourcc('N', 'V', '2', '1'), "NV21", GreyConversion::kLumaPlane},
    {fourcc('Y', 'V', '1', '2'), "YVU420", GreyConversion::kLumaPlane},
    {fourcc('N', 'V', '1', '6'), "NV16", GreyConversion::kLumaPlane},
    {fourcc('N', 'V', '6', '1'), "NV61", GreyConversion::kLumaPlane},
    {fourcc('Y', 'U', '1', '6'), "YUV422", GreyConversion::kLumaPlane},
    {fourcc('Y', 'U', 'Y', 'V'), "YUYV", GreyConversion::kPackedLuma0},
    {fourcc('Y', 'V', 'Y', 'U'), "YVYU", GreyConversion::kPackedLuma0},
    {fourcc('U', 'Y', 'V', 'Y'), "UYVY", GreyConversion::kPackedLuma1},
    {fourcc('V', 'Y', 'U', 'Y'), "VYUY", GreyConversion::kPackedLuma1},
    {fourcc('M', 'J', 'P', 'G'), "MJPEG", GreyConversion::kJpeg},
};

std::string upper(std::string_view s) {
  std::string u(s);
  for (char& c : u) c = static_cast<char>(std::toupper(static_cast<unsigned char>(c)));
  return u;
}

std::string joinFormats(std::span<const std::uint32_t> formats) {
  std::string s;
  for (std::uint32_t f : formats) {
    if (!s.empty()) s += ' ';
    s += formatName(f);
  }
  return s.empty() ? "nothing" : s;
}

std::string joinIds(std::span<const std::string> ids) {
  std::string s;
  for (std::size_t i = 0; i < ids.size(); ++i) {
    if (i) s += ", ";
    s += std::to_string(i) + ": " + ids[i];
  }
  return s;
}

}  // namespace

std::span<const GreyFormat> greyFormats() { return kGreyFormats; }

const GreyFormat* findGreyFormat(std::uint32_t f) {
  for (const GreyFormat& g : kGreyFormats)
    if (g.fourcc == f) return &g;
  return nullptr;
}

std::optional<std::uint32_t> parseFormatName(std::string_view name) {
  const std::string u = upper(name);
  if (u.empty() || u == "AUTO") return 0u;
  if (u == "GREY" || u == "GRAY" || u == "Y8") return fourcc('R', '8', ' ', ' ');
  if (u == "MJPG" || u == "JPEG") return fourcc('M', 'J', 'P', 'G');
  if (u == "YUY2") return fourcc('Y', 'U', 'Y', 'V');
  if (u == "I420") return fourcc('Y', 'U', '1', '2');
  for (const GreyFormat& g : kGreyFormats)
    if (u == g.name) return g.fourcc;
  return std::nullopt;
}

std::string formatName(std::uint32_t f) {
  if (const GreyFormat* g = findGreyFormat(f)) return g->name;
  std::string s(4, ' ');
  for (int i = 0; i < 4; ++i) {
    const char c = static_cast<char>((f >> (8 * i)) & 0xFF);
    s[static_cast<std::size_t>(i)] = (c >= 32 && c < 127) ? c : '?';
  }
  while (!s.empty() && s.back() == ' ') s.pop_back();
  return s;
}

Expected<FormatChoice> chooseFormat(std::string_view requested,
                                    std::span<const std::uint32_t> offered) {
  const auto wanted = parseFormatName(requested);
  if (!wanted)
    return fail(ErrorCode::kInvalidArgument,
                "format '%.*s' cannot be turned into grey (use auto, R8/GREY, NV12, YUV420, "
                "YUYV, UYVY, MJPEG, ...)",
                static_cast<int>(requested.size()), requested.data());
  const bool is_offered =
      std::find(offered.begin(), offered.end(), *wanted) != offered.end();
  if (*wanted != 0 && is_offered) return FormatChoice{*wanted, false};
  // Auto, or not offered: the best convertible format the camera has.
  for (const GreyFormat& g : kGreyFormats)
    if (std::find(offered.begin(), offered.end(), g.fourcc) != offered.end())
      return FormatChoice{g.fourcc, *wanted != 0};
  return fail(ErrorCode::kUnsupportedFormat,
              "the camera offers no format that converts to grey (offers: %s)",
              joinFormats(offered).c_str());
}

CameraSelector parseCameraSelector(std::string_view camera) {
  CameraSelector s;
  const bool digits = !camera.empty() && camera.size() <= 6 &&
                      std::all_of(camera.begin(), camera.end(),
                                  [](char c) { return std::isdigit(static_cast<unsigned char>(c)); });
  if (digits) s.index = static_cast<std::size_t>(std::stoul(std::string(camera)));
  else s.id = std::string(camera);
  return s;
}

Expected<std::size_t> selectCamera(const CameraSelector& selector,
                                   std::span<const std::string> ids) {
  if (ids.empty())
    return fail(ErrorCode::kNoDevice,
                "no camera: libcamera found none (connected? enabled in the firmware? "
                "is another process holding it?)");
  if (selector.index) {
    if (*selector.index >= ids.size())
      return fail(ErrorCode::kNoDevice, "no camera %zu: libcamera found %zu (%s)", *selector.index,
                  ids.size(), joinIds(ids).c_str());
    return *selector.index;
  }
  for (std::size_t i = 0; i < ids.size(); ++i)
    if (ids[i] == selector.id) return i;
  return fail(ErrorCode::kNotFound, "no camera with id '%s'; libcamera found %s",
              selector.id.c_str(), joinIds(ids).c_str());
}

std::int64_t frameDurationUs(double fps) { return std::llround(1e6 / fps); }

}  // namespace omnipose::libcam

namespace omnipose {

std::vector<std::string> validate(const LibcameraOptions& o) {
  std::vector<std::string> problems;
  if (o.camera.empty())
    problems.push_back("source.camera: must be an index (0, 1, ...) or a libcamera camera id");
  drivers::appendStreamRequestProblems(problems, o.width, o.height, o.fps);
  if (!libcam::parseFormatName(o.format))
    problems.push_back("source.format: '" + o.format +
                       "' cannot be turned into grey (auto, R8/GREY, NV12, YUV420, YUYV, UYVY, "
                       "MJPEG, ...)");
  if (o.buffer_count < 1 || o.buffer_count > 32)
    problems.push_back("buffer_count: must be in [1, 32], is " + std::to_string(o.buffer_count));
  drivers::appendClockProblems(problems, o.clock_resync, o.clock_samples);
  return problems;
}

}  // namespace omnipose
