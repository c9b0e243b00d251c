#pragma once
/// \file image_decode.hpp
/// The one way omnipose decodes an image file or an encoded buffer (dataset frames, masks,
/// textures, calibration frames, MJPG camera frames). Every decode:
///  - reads the size the file declares from its header first (PNG, JPEG, PNM, BMP; nothing
///    else is accepted) and refuses, before any pixel is decoded, an image whose declared
///    size is not the expected one or exceeds the pixel bound, so a 138-byte "60000 x 60000"
///    PNG costs nothing;
///  - refuses files that are not regular files (FIFOs, devices) or larger than the byte bound;
///  - catches every decoder exception;
///  - names the file (or the caller's label for a buffer) in every error.
/// Errors are values (kNotFound for a missing file, kBadFrame for everything else about the
/// content, kIoError for a read failure); nothing here throws.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <opencv2/core.hpp>
#include <span>
#include <vector>

#include "omnipose/error.hpp"

namespace omnipose {

/// The container formats the decoder accepts.
enum class ImageFormat { kPng, kJpeg, kPnm, kBmp };

/// What an image header declares, read without decoding any pixel.
struct ImageHeader {
  ImageFormat format = ImageFormat::kPng;
  int width = 0;   ///< pixels
  int height = 0;  ///< pixels
};

/// How the decoded pixels are delivered.
enum class ImageColour {
  kAsStored,  ///< grey stays grey, colour stays BGR(A); 8 or 16 bit as stored
  kGrey,      ///< 8-bit grey
  kBgr,       ///< 8-bit BGR
};

/// Bounds on one decode. The defaults bound a photo or calibration frame; a dataset frame
/// or a camera frame also sets `exact_size`.
struct ImageLimits {
  /// Largest image accepted, in pixels (width x height as declared by the header):
  /// 2^26 = 67 megapixels (8192 x 8192), far above any camera or 360-degree photo omnipose
  /// reads, far below what would exhaust a robot's memory.
  std::int64_t max_pixels = std::int64_t{1} << 26;
  /// Largest file accepted, in bytes (256 MiB; an ASCII PPM stores up to 12 bytes a pixel).
  std::uintmax_t max_file_bytes = std::uintmax_t{256} << 20;
  /// When non-empty, the declared size must be exactly this (e.g. the calibration's frame
  /// size); checked before decoding.
  cv::Size exact_size{};
  /// Apply a JPEG's EXIF orientation (what a photo viewer shows). Off for camera frames,
  /// whose pixels must stay where the sensor put them.
  bool apply_exif_orientation = false;
};

/// Reads the header of an encoded image. kBadFrame (naming `label`) when the bytes are not a
/// PNG, JPEG, PNM or BMP, or the header is truncated or declares an empty or negative size.
Expected<ImageHeader> readImageHeader(std::span<const std::uint8_t> bytes, const char* label);

/// Reads an image file (with readImage()'s file checks, into `buffer`) and returns the header
/// it declares, decoding no pixel.
Expected<ImageHeader> readImageHeader(const std::filesystem::path& path, const ImageLimits& limits,
                                      std::vector<std::uint8_t>& buffer);

/// Decodes an image into `out` after the header checks above. `out` is reused when its size
/// and type already match (a camera's steady state allocates nothing then). On failure `out`
/// is left empty or unchanged and the error names `label`.
Expected<void> decodeImage(std::span<const std::uint8_t> bytes, ImageColour colour,
                           const ImageLimits& limits, const char* label, cv::Mat& out);

/// Reads and decodes one image file, reusing `buffer` for the file's bytes.
Expected<void> readImage(const std::filesystem::path& path, ImageColour colour,
                         const ImageLimits& limits, std::vector<std::uint8_t>& buffer,
                         cv::Mat& out);

/// Convenience form of readImage() that allocates its own buffers.
Expected<cv::Mat> readImage(const std::filesystem::path& path, ImageColour colour,
                            const ImageLimits& limits = {});

}  // namespace omnipose
