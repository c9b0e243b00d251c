#pragma once
/// \file grey_convert.hpp
/// Camera buffers to 8-bit grey, written into a caller-owned CV_8UC1 Mat that is never
/// reallocated. Luma planes and packed 4:2:2 are copied without any allocation; JPEG
/// decoding allocates (the decoder object and libjpeg's working memory, inside OpenCV),
/// which is accepted for MJPG cameras.

#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>

#include "omnipose/error.hpp"

namespace omnipose::drivers {

/// Bytes a frame of `rows` rows must at least hold when rows are `stride` bytes apart and
/// each carries `row_bytes` bytes of pixels: stride * (rows - 1) + row_bytes.
constexpr std::size_t minimumFrameBytes(std::size_t stride, std::size_t row_bytes, int rows) {
  return rows <= 0 ? 0 : stride * static_cast<std::size_t>(rows - 1) + row_bytes;
}

/// Copies an 8-bit plane (GREY, or the Y plane of NV12 / YUV420 / ...) whose rows are
/// `stride` bytes apart into `out` (out.cols bytes of each of out.rows rows).
/// Preconditions: out is CV_8UC1, stride >= out.cols, src holds
/// minimumFrameBytes(stride, out.cols, out.rows) bytes. No allocation.
void copyLumaPlane(const std::uint8_t* src, std::size_t stride, cv::Mat& out);

/// Packed 4:2:2 to grey: takes the luma byte of every pixel pair. YUYV / YVYU:
/// luma_offset 0 (Y0 U Y1 V), UYVY / VYUY: luma_offset 1 (U Y0 V Y1).
/// Preconditions: out is CV_8UC1 with an even or odd width (the last luma of an odd
/// width is read from its pair), stride >= 2 * out.cols, src holds
/// minimumFrameBytes(stride, 2 * out.cols, out.rows) bytes. No allocation.
void packedYuv422ToGrey(const std::uint8_t* src, std::size_t stride, int luma_offset,
                        cv::Mat& out);

/// Decodes one JPEG (an MJPG frame) to grey (libjpeg outputs the luma channel directly;
/// EXIF orientation is ignored) into `scratch`, checks its size and copies it into `out`.
/// `scratch` is reused between calls. Errors: kBadFrame when the data is not a JPEG,
/// cannot be decoded, or decodes to another size than out. Allocates (see file comment).
Expected<void> decodeJpegToGrey(const std::uint8_t* data, std::size_t size, cv::Mat& scratch,
                                cv::Mat& out);

}  // namespace omnipose::drivers
