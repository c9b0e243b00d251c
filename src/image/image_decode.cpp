#include "omnipose/image_decode.hpp"
#include "omnipose/file_io.hpp"

#include <algorithm>
#include <climits>
#include <cstdio>
#include <cstring>
#include <exception>
#include <opencv2/imgcodecs.hpp>
#include <system_error>

namespace omnipose {
namespace {

const char* formatName(ImageFormat format) {
  switch (format) {
    case ImageFormat::kPng: return "PNG";
    case ImageFormat::kJpeg: return "JPEG";
    case ImageFormat::kPnm: return "PNM";
    case ImageFormat::kBmp: return "BMP";
  }
  return "image";
}

std::uint32_t bigEndian32(const std::uint8_t* p) {
  return (std::uint32_t{p[0]} << 24) | (std::uint32_t{p[1]} << 16) | (std::uint32_t{p[2]} << 8) |
         std::uint32_t{p[3]};
}
std::uint32_t bigEndian16(const std::uint8_t* p) { return (std::uint32_t{p[0]} << 8) | p[1]; }
std::uint32_t littleEndian32(const std::uint8_t* p) {
  return std::uint32_t{p[0]} | (std::uint32_t{p[1]} << 8) | (std::uint32_t{p[2]} << 16) |
         (std::uint32_t{p[3]} << 24);
}
std::uint32_t littleEndian16(const std::uint8_t* p) { return std::uint32_t{p[0]} | (std::uint32_t{p[1]} << 8); }

/// A declared size as a header, or kBadFrame when it is empty or beyond int.
Expected<ImageHeader> sized(ImageFormat format, std::int64_t width, std::int64_t height,
                            const char* label) {
  if (width <= 0 || height <= 0 || width > INT_MAX || height > INT_MAX) {
    return fail(ErrorCode::kBadFrame, "%s: cannot decode: %s header declares an invalid size %lldx%lld", label,
                formatName(format), static_cast<long long>(width), static_cast<long long>(height));
  }
  return ImageHeader{format, static_cast<int>(width), static_cast<int>(height)};
}

Expected<ImageHeader> pngHeader(std::span<const std::uint8_t> b, const char* label) {
  // Signature (8 bytes), then the IHDR chunk: length (4), "IHDR", width (4), height (4).
  if (b.size() < 24 || b[12] != 'I' || b[13] != 'H' || b[14] != 'D' || b[15] != 'R')
    return fail(ErrorCode::kBadFrame, "%s: cannot decode: PNG without a complete IHDR header", label);
  return sized(ImageFormat::kPng, bigEndian32(&b[16]), bigEndian32(&b[20]), label);
}

/// Offset of the first frame header (SOF0-15 except DHT C4, JPG C8 and DAC CC) after SOI,
/// walking the marker segments by their lengths; 0 when there is none before the scan.
std::size_t jpegFrameHeaderAt(std::span<const std::uint8_t> b) {
  std::size_t pos = 2;
  while (pos + 3 < b.size()) {
    if (b[pos] != 0xFF) return 0;
    const std::uint8_t marker = b[pos + 1];
    if (marker == 0xFF) {  // fill byte
      ++pos;
      continue;
    }
    if (marker == 0x01 || (marker >= 0xD0 && marker <= 0xD8)) {  // no length field
      pos += 2;
      continue;
    }
    if (marker == 0xD9 || marker == 0xDA) return 0;  // end of image or scan before any frame
    const std::size_t length = bigEndian16(&b[pos + 2]);
    if (length < 2) return 0;
    if (marker >= 0xC0 && marker <= 0xCF && marker != 0xC4 && marker != 0xC8 && marker != 0xCC)
      return pos;
    pos += 2 + length;
  }
  return 0;
}

Expected<ImageHeader> jpegHeader(std::span<const std::uint8_t> b, const char* label) {
  // Frame header: marker (2), length (2), precision (1), height (2), width (2).
  const std::size_t at = jpegFrameHeaderAt(b);
  if (at == 0 || at + 9 > b.size())
    return fail(ErrorCode::kBadFrame, "%s: cannot decode: JPEG without a frame header (truncated?)", label);
  return sized(ImageFormat::kJpeg, bigEndian16(&b[at + 7]), bigEndian16(&b[at + 5]), label);
}

/// Whether the end-of-image marker (FF D9) follows the frame header. In entropy-coded data a
/// 0xFF byte is always followed by 0x00 or a restart marker, so the last FF D9 after the
/// frame header is the image's own end (an EXIF thumbnail's comes before the frame header).
bool hasJpegEnd(std::span<const std::uint8_t> b) {
  const std::size_t at = jpegFrameHeaderAt(b);
  if (at == 0) return false;
  for (std::size_t i = b.size() - 1; i > at + 1; --i) {
    if (b[i] == 0xD9 && b[i - 1] == 0xFF) return true;
  }
  return false;
}

Expected<ImageHeader> pnmHeader(std::span<const std::uint8_t> b, const char* label) {
  // "P1".."P6", then width and height as decimal tokens separated by white space and
  // '#' comments.
  std::size_t pos = 2;
  std::int64_t values[2] = {0, 0};
  for (std::int64_t& value : values) {
    for (;;) {
      while (pos < b.size() && (b[pos] == ' ' || b[pos] == '\t' || b[pos] == '\r' ||
                                b[pos] == '\n' || b[pos] == '\v' || b[pos] == '\f'))
        ++pos;
      if (pos < b.size() && b[pos] == '#') {
        while (pos < b.size() && b[pos] != '\n') ++pos;
        continue;
      }
      break;
    }
    const std::size_t start = pos;
    while (pos < b.size() && b[pos] >= '0' && b[pos] <= '9' && pos - start < 11) {
      value = value * 10 + (b[pos] - '0');
      ++pos;
    }
    if (pos == start) return fail(ErrorCode::kBadFrame, "%s: cannot decode: PNM header without a size", label);
  }
  return sized(ImageFormat::kPnm, values[0], values[1], label);
}

Expected<ImageHeader> bmpHeader(std::span<const std::uint8_t> b, const char* label) {
  // File header (14 bytes), then the DIB header: its size (4), then width and height:
  // 16-bit for the 12-byte OS/2 header, signed 32-bit otherwise (negative height = top-down).
  if (b.size() < 26) return fail(ErrorCode::kBadFrame, "%s: cannot decode: BMP header truncated", label);
  const std::uint32_t dib = littleEndian32(&b[14]);
  if (dib == 12) return sized(ImageFormat::kBmp, littleEndian16(&b[18]), littleEndian16(&b[20]), label);
  if (dib < 40) return fail(ErrorCode::kBadFrame, "%s: cannot decode: BMP with an unknown %u-byte header", label, dib);
  const auto width = static_cast<std::int32_t>(littleEndian32(&b[18]));
  const auto height = static_cast<std::int32_t>(littleEndian32(&b[22]));
  const std::int64_t rows = height < 0 ? -static_cast<std::int64_t>(height) : height;
  return sized(ImageFormat::kBmp, width, rows, label);
}

/// Whether a PNG's IEND chunk is there (looked for near the end: a few writers append bytes
/// after it). libpng reports a truncated file on stderr before OpenCV returns.
bool hasPngEnd(std::span<const std::uint8_t> b) {
  static constexpr std::uint8_t kIend[4] = {'I', 'E', 'N', 'D'};
  const std::size_t window = std::min<std::size_t>(b.size(), 4096);
  const auto tail = b.last(window);
  return std::search(tail.begin(), tail.end(), kIend, kIend + 4) != tail.end();
}

}  // namespace

Expected<ImageHeader> readImageHeader(std::span<const std::uint8_t> b, const char* label) {
  static constexpr std::uint8_t kPngSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  if (b.size() >= 8 && std::equal(kPngSignature, kPngSignature + 8, b.begin())) return pngHeader(b, label);
  if (b.size() >= 3 && b[0] == 0xFF && b[1] == 0xD8 && b[2] == 0xFF) return jpegHeader(b, label);
  if (b.size() >= 2 && b[0] == 'P' && b[1] >= '1' && b[1] <= '6') return pnmHeader(b, label);
  if (b.size() >= 2 && b[0] == 'B' && b[1] == 'M') return bmpHeader(b, label);
  if (b.empty()) return fail(ErrorCode::kBadFrame, "%s: cannot decode: empty file", label);
  return fail(ErrorCode::kBadFrame, "%s: cannot decode: not a PNG, JPEG, PNM or BMP image", label);
}

Expected<void> decodeImage(std::span<const std::uint8_t> bytes, ImageColour colour,
                           const ImageLimits& limits, const char* label, cv::Mat& out) {
  const Expected<ImageHeader> header = readImageHeader(bytes, label);
  if (!header) return std::unexpected(header.error());
  const int width = header->width;
  const int height = header->height;
  if (!limits.exact_size.empty() &&
      (width != limits.exact_size.width || height != limits.exact_size.height)) {
    return fail(ErrorCode::kBadFrame, "%s: %dx%d, expected %dx%d", label, width, height,
                limits.exact_size.width, limits.exact_size.height);
  }
  if (static_cast<std::int64_t>(width) * height > limits.max_pixels) {
    return fail(ErrorCode::kBadFrame, "%s: declares %dx%d pixels, more than the %lld allowed", label,
                width, height, static_cast<long long>(limits.max_pixels));
  }
  if (bytes.size() > static_cast<std::size_t>(INT_MAX) || bytes.size() > limits.max_file_bytes) {
    return fail(ErrorCode::kBadFrame, "%s: %zu bytes, more than the %ju allowed", label,
                bytes.size(), static_cast<std::uintmax_t>(limits.max_file_bytes));
  }

  if (header->format == ImageFormat::kPng && !hasPngEnd(bytes)) {
    return fail(ErrorCode::kBadFrame, "%s: cannot decode: PNG without its IEND chunk (truncated?)", label);
  }
  if (header->format == ImageFormat::kJpeg && !hasJpegEnd(bytes)) {
    // libjpeg fills a truncated scan with grey and only warns: refuse it here.
    return fail(ErrorCode::kBadFrame, "%s: cannot decode: JPEG without its end-of-image marker (truncated?)",
                label);
  }

  int flags = cv::IMREAD_UNCHANGED;
  if (colour == ImageColour::kGrey) flags = cv::IMREAD_GRAYSCALE;
  if (colour == ImageColour::kBgr) flags = cv::IMREAD_COLOR;
  if (colour != ImageColour::kAsStored && !limits.apply_exif_orientation)
    flags |= cv::IMREAD_IGNORE_ORIENTATION;

  const cv::Mat encoded(1, static_cast<int>(bytes.size()), CV_8UC1,
                        const_cast<std::uint8_t*>(bytes.data()));
  try {
    cv::imdecode(encoded, flags, &out);
  } catch (const cv::Exception& e) {
    out.release();
    return fail(ErrorCode::kBadFrame, "%s: cannot decode %s image: %s", label,
                formatName(header->format), e.err.c_str());
  } catch (const std::exception& e) {
    out.release();
    return fail(ErrorCode::kBadFrame, "%s: cannot decode image: %s", label, e.what());
  } catch (...) {
    out.release();
    return fail(ErrorCode::kBadFrame, "%s: cannot decode image", label);
  }
  if (out.empty()) return fail(ErrorCode::kBadFrame, "%s: cannot decode image (corrupt or truncated?)", label);
  const bool as_declared = out.cols == width && out.rows == height;
  const bool rotated = limits.apply_exif_orientation && out.cols == height && out.rows == width;
  if (!as_declared && !rotated) {
    const int cols = out.cols, rows = out.rows;
    out.release();
    return fail(ErrorCode::kBadFrame, "%s: decoded to %dx%d, the header declares %dx%d", label,
                cols, rows, width, height);
  }
  return {};
}

namespace {

/// The bytes of an image file into `buffer`, with the file checks of readImage(): a regular
/// file (opened without blocking) of at most limits.max_file_bytes, read whole. A file that
/// is not regular, too large or changed while read is a bad frame.
Expected<std::span<const std::uint8_t>> readFileBytes(const std::filesystem::path& path,
                                                      const ImageLimits& limits,
                                                      std::vector<std::uint8_t>& buffer) {
  if (Expected<void> read = readRegularFile(path, limits.max_file_bytes, buffer); !read) {
    const ErrorCode code = read.error().code() == ErrorCode::kInvalidArgument ? ErrorCode::kBadFrame
                                                                               : read.error().code();
    return std::unexpected(Error(code, read.error().message()));
  }
  return std::span<const std::uint8_t>(buffer.data(), buffer.size());
}

}  // namespace

Expected<ImageHeader> readImageHeader(const std::filesystem::path& path, const ImageLimits& limits,
                                      std::vector<std::uint8_t>& buffer) {
  const Expected<std::span<const std::uint8_t>> bytes = readFileBytes(path, limits, buffer);
  if (!bytes) return std::unexpected(bytes.error());
  return readImageHeader(*bytes, path.c_str());
}

Expected<void> readImage(const std::filesystem::path& path, ImageColour colour,
                         const ImageLimits& limits, std::vector<std::uint8_t>& buffer,
                         cv::Mat& out) {
  const Expected<std::span<const std::uint8_t>> bytes = readFileBytes(path, limits, buffer);
  if (!bytes) return std::unexpected(bytes.error());
  return decodeImage(*bytes, colour, limits, path.c_str(), out);
}

Expected<cv::Mat> readImage(const std::filesystem::path& path, ImageColour colour,
                            const ImageLimits& limits) {
  std::vector<std::uint8_t> buffer;
  cv::Mat out;
  if (Expected<void> read = readImage(path, colour, limits, buffer, out); !read)
    return std::unexpected(read.error());
  return out;
}

}  // namespace omnipose
