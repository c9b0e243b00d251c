#include "common/grey_convert.hpp"

#include <cstring>
#include <opencv2/imgcodecs.hpp>

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
  const cv::Mat encoded(1, static_cast<int>(size), CV_8UC1, const_cast<std::uint8_t*>(data));
  try {
    cv::imdecode(encoded, cv::IMREAD_GRAYSCALE | cv::IMREAD_IGNORE_ORIENTATION, &scratch);
  } catch (const cv::Exception& e) {
    return fail(ErrorCode::kBadFrame, "MJPG frame of %zu bytes could not be decoded: %s", size,
                e.what());
  }
  if (scratch.empty())
    return fail(ErrorCode::kBadFrame, "MJPG frame of %zu bytes could not be decoded", size);
  if (scratch.type() != CV_8UC1 || scratch.size() != out.size())
    return fail(ErrorCode::kBadFrame, "MJPG frame decodes to %dx%d, expected %dx%d", scratch.cols,
                scratch.rows, out.cols, out.rows);
  scratch.copyTo(out);
  return {};
}

}  // namespace omnipose::drivers
