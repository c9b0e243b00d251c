#include "common/grey_convert.hpp"

#include <cstring>
#include <cstdio>

#include "omnipose/image_decode.hpp"

namespace omnipose::drivers {

void copyLumaPlane(const std::uint8_t* src, std::size_t stride, cv::Mat& out) {
  const std::size_t width = static_cast<std::size_t>(out.cols);
  if (out.isContinuous() && stride == width) {
    std::memcpy(out.data, src, width * static_cast<std::size_t>(out.rows));
    return;
  }
  for (int r = 0; r < out.rows; ++r)
    std::memcpy(out.ptr<std::uint8_t>(r), src + static_cast<std::size_t>(r) * stride, width);
}

void packedYuv422ToGrey(const std::uint8_t* src, std::size_t stride, int luma_offset,
                        cv::Mat& out) {
  const int width = out.cols;
  for (int r = 0; r < out.rows; ++r) {
    // Every pixel owns two bytes; its luma is the byte at luma_offset.
    const std::uint8_t* in = src + static_cast<std::size_t>(r) * stride + luma_offset;
    std::uint8_t* o = out.ptr<std::uint8_t>(r);
    for (int x = 0; x < width; ++x) o[x] = in[2 * x];
  }
}

Expected<void> decodeJpegToGrey(const std::uint8_t* data, std::size_t size, cv::Mat& scratch,
                                cv::Mat& out) {
  // SOI marker first: anything else is not a JPEG (e.g. a truncated or empty buffer).
  if (size < 4 || data[0] != 0xFF || data[1] != 0xD8)
    return fail(ErrorCode::kBadFrame, "MJPG frame of %zu bytes does not start with a JPEG SOI marker",
                size);
  char label[48];
  std::snprintf(label, sizeof label, "MJPG frame of %zu bytes", size);
  ImageLimits limits;
  limits.exact_size = out.size();
  if (Expected<void> decoded = decodeImage(std::span<const std::uint8_t>(data, size),
                                           ImageColour::kGrey, limits, label, scratch);
      !decoded) {
    return decoded;
  }
  scratch.copyTo(out);
  return {};
}

}  // namespace omnipose::drivers
