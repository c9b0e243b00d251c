#pragma once
// Hostile image files for the decoder's tests (io, replay, daemon): decompression bombs whose
// header declares a huge size, and truncated or garbage PNG, JPEG, PGM and BMP files. Every
// file is built here from its format's definition, so the tests need no binary fixtures.

#include <zlib.h>

#include <cstdint>
#include <filesystem>
#include <algorithm>
#include <fstream>
#include <map>
#include <opencv2/imgcodecs.hpp>
#include <random>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace omnipose::testing {

using Bytes = std::vector<std::uint8_t>;

inline void appendBigEndian32(Bytes& out, std::uint32_t v) {
  for (int shift = 24; shift >= 0; shift -= 8) out.push_back(static_cast<std::uint8_t>(v >> shift));
}

/// One PNG chunk: length, type, data, CRC over type and data.
inline void appendPngChunk(Bytes& out, const char type[4], const Bytes& data) {
  appendBigEndian32(out, static_cast<std::uint32_t>(data.size()));
  const std::size_t type_at = out.size();
  out.insert(out.end(), type, type + 4);
  out.insert(out.end(), data.begin(), data.end());
  const uLong crc = crc32(0L, out.data() + type_at, static_cast<uInt>(4 + data.size()));
  appendBigEndian32(out, static_cast<std::uint32_t>(crc));
}

inline Bytes pngSignatureAndHeader(std::uint32_t width, std::uint32_t height) {
  Bytes png = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1A, '\n'};
  Bytes ihdr;
  appendBigEndian32(ihdr, width);
  appendBigEndian32(ihdr, height);
  ihdr.insert(ihdr.end(), {8, 0, 0, 0, 0});  // 8-bit grey, deflate, no filter, no interlace
  appendPngChunk(png, "IHDR", ihdr);
  return png;
}

/// A PNG that declares width x height pixels but holds only the first rows' worth of data
/// (a decoder that trusts the header allocates width x height bytes first).
inline Bytes pngBomb(std::uint32_t width, std::uint32_t height, bool with_data = true) {
  Bytes png = pngSignatureAndHeader(width, height);
  if (!with_data) return png;
  Bytes row(1 + 64, 0);  // filter byte + a few pixels: the stream ends early
  Bytes idat(compressBound(static_cast<uLong>(row.size())));
  uLongf size = static_cast<uLongf>(idat.size());
  compress2(idat.data(), &size, row.data(), static_cast<uLong>(row.size()), 9);
  idat.resize(size);
  appendPngChunk(png, "IDAT", idat);
  appendPngChunk(png, "IEND", {});
  return png;
}

/// A complete, valid grey PNG of width x height zeros, deflated row by row without ever
/// holding the image (32000 x 32000 is about 1 MB of file for 1 GB of pixels).
inline Bytes zeroPng(std::uint32_t width, std::uint32_t height) {
  Bytes png = pngSignatureAndHeader(width, height);
  z_stream z{};
  if (deflateInit(&z, Z_BEST_SPEED) != Z_OK) throw std::runtime_error("deflateInit failed");
  Bytes row(1 + width, 0);
  Bytes idat;
  Bytes chunk(1 << 16);
  for (std::uint32_t r = 0; r <= height; ++r) {
    const bool last = r == height;
    z.next_in = last ? nullptr : row.data();
    z.avail_in = last ? 0 : static_cast<uInt>(row.size());
    do {
      z.next_out = chunk.data();
      z.avail_out = static_cast<uInt>(chunk.size());
      deflate(&z, last ? Z_FINISH : Z_NO_FLUSH);
      idat.insert(idat.end(), chunk.begin(), chunk.end() - z.avail_out);
    } while (z.avail_out == 0);
  }
  deflateEnd(&z);
  appendPngChunk(png, "IDAT", idat);
  appendPngChunk(png, "IEND", {});
  return png;
}

/// A baseline JPEG header whose frame header (SOF0) declares width x height, then EOI.
inline Bytes jpegBomb(std::uint16_t width, std::uint16_t height) {
  return {0xFF, 0xD8,                                      // SOI
          0xFF, 0xC0, 0x00, 0x0B, 0x08,                    // SOF0, length 11, 8 bit
          static_cast<std::uint8_t>(height >> 8), static_cast<std::uint8_t>(height),
          static_cast<std::uint8_t>(width >> 8), static_cast<std::uint8_t>(width),
          0x01, 0x01, 0x11, 0x00,                          // one component
          0xFF, 0xD9};                                     // EOI
}

inline Bytes encode(const cv::Mat& image, const std::string& ext) {
  Bytes out;
  if (!cv::imencode(ext, image, out)) throw std::runtime_error("cannot encode " + ext);
  return out;
}

inline Bytes garbage(std::size_t size, std::uint32_t seed) {
  std::mt19937 rng(seed);
  Bytes out(size);
  for (auto& b : out) b = static_cast<std::uint8_t>(rng());
  return out;
}

/// A hostile file: its name (with the ending of the format it pretends to be), its bytes,
/// and whether every decoder must refuse it (a scrambled JPEG's entropy data may still decode
/// to an image of the right size: then only its bounds are checked).
struct BadImageFile {
  std::string name;
  Bytes bytes;
  bool must_reject = true;
};

/// Hostile files made from a good frame: bombs, and each of PNG, JPEG, PGM and BMP truncated
/// (inside the header, and half way) and replaced by garbage; PNG and JPEG also scrambled
/// after their headers.
inline std::vector<BadImageFile> badImageFiles(const cv::Mat& good_frame) {
  std::vector<BadImageFile> files;
  files.push_back({"bomb_header_only.png", pngBomb(60000, 60000, false)});
  files.push_back({"bomb_60000.png", pngBomb(60000, 60000)});
  files.push_back({"bomb_60000.jpg", jpegBomb(60000, 60000)});
  for (const std::string ext : {".png", ".jpg", ".pgm", ".bmp"}) {
    const Bytes good = encode(good_frame, ext);
    const std::string stem = ext.substr(1);
    files.push_back({"truncated_header_" + stem + ext, Bytes(good.begin(), good.begin() + 12)});
    files.push_back({"truncated_half_" + stem + ext,
                     Bytes(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(good.size() / 2))});
    Bytes noise = garbage(4096, 11);
    noise[0] = 0;  // no format starts with a zero byte
    files.push_back({"garbage_" + stem + ext, noise});
    if (ext == ".png" || ext == ".jpg") {
      Bytes scrambled = good;
      const Bytes random = garbage(good.size(), 7);
      for (std::size_t i = good.size() / 2; i + 2 < good.size(); ++i) scrambled[i] = random[i];
      files.push_back({"scrambled_" + stem + ext, scrambled, ext == ".png"});
    }
  }
  return files;
}

inline void writeBytes(const std::filesystem::path& path, const Bytes& bytes) {
  std::ofstream out(path, std::ios::binary | std::ios::trunc);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

/// Inserts `files` into a dataset directory right after the frame at sorted position `after`
/// (frames/ and, when there is one, timestamps.txt: each file gets a timestamp of its own
/// between that frame's and the next one's, so the dataset stays valid).
inline void insertFrames(const std::filesystem::path& dataset, std::size_t after,
                         const std::vector<BadImageFile>& files) {
  std::vector<std::filesystem::path> frames;
  for (const auto& e : std::filesystem::directory_iterator(dataset / "frames")) frames.push_back(e.path());
  std::sort(frames.begin(), frames.end());
  if (after + 1 >= frames.size()) throw std::invalid_argument("insertFrames: no frame after the position");
  const std::string stem = frames[after].stem().string();
  const std::filesystem::path stamps_path = dataset / "timestamps.txt";
  std::map<std::string, double> stamps;
  if (std::filesystem::exists(stamps_path)) {
    std::ifstream in(stamps_path);
    std::string name;
    double t = 0;
    while (in >> name >> t) stamps[name] = t;
  }
  const double t0 = stamps[frames[after].filename().string()];
  const double t1 = stamps[frames[after + 1].filename().string()];
  for (std::size_t k = 0; k < files.size(); ++k) {
    const std::string name = stem + "_" + files[k].name;  // sorts between the two frames
    writeBytes(dataset / "frames" / name, files[k].bytes);
    stamps[name] = t0 + (t1 - t0) * static_cast<double>(k + 1) / static_cast<double>(files.size() + 1);
  }
  if (!std::filesystem::exists(stamps_path)) return;
  std::ofstream out(stamps_path, std::ios::trunc);
  out.precision(17);
  for (const auto& [name, t] : stamps) out << name << " " << t << "\n";
}

}  // namespace omnipose::testing
