// A Linux IIO device's scan format and scans (drivers/iio/iio_scan.hpp), as a device under
// a broken or hostile driver could present them: parseScanType on a `_type` text,
// parseSysfsNumber on it as a `_scale`, computeLayout of the gyro's channels with that type,
// then decodeScan on the rest of the input, scan by scan.
// Input: a `_type` text up to the first '\n'; one byte of channel indices (bits 0-1: the
// rate axes' first index, bits 2-3: the timestamp's index among them); then scan bytes.
// Invariants: never a read outside the input, a layout's fields inside its scan, a raw value
// within its type's rails, and a scan judged kOk only with a timestamp after the previous
// good one and finite rates.
#include <cmath>
#include <cstdint>
#include <span>
#include <string_view>

#include "iio/iio_scan.hpp"

namespace iio = omnipose::iio;

namespace {

void decodeAll(std::span<const std::uint8_t> bytes, const iio::ScanLayout& layout) {
  const iio::RateScale scale{{0.000266, 0.001065, 1e-9}, {0.0, -2.0, 5.0}};
  std::int64_t previous = 0;
  for (std::size_t at = 0; at + layout.scan_bytes <= bytes.size(); at += layout.scan_bytes) {
    const auto scan = bytes.subspan(at, layout.scan_bytes);
    for (const auto& f : layout.rate) {
      if (f.offset + static_cast<std::size_t>(f.type.storageBytes()) > layout.scan_bytes) __builtin_trap();
      const std::int64_t raw = iio::extractRaw(scan, f);
      if (raw < f.type.minRaw() || raw > f.type.maxRaw()) __builtin_trap();
    }
    const iio::DecodedScan d = iio::decodeScan(scan, layout, scale, previous);
    if (d.verdict == iio::ScanVerdict::kOk) {
      if (d.timestamp_ns <= previous || !d.sample.rate.allFinite()) __builtin_trap();
      previous = d.timestamp_ns;
    }
  }
  // A short tail is a partial scan, never read.
  if (bytes.size() % layout.scan_bytes != 0) {
    const auto tail = bytes.subspan(bytes.size() - bytes.size() % layout.scan_bytes);
    if (iio::decodeScan(tail, layout, scale, previous).verdict != iio::ScanVerdict::kTruncated)
      __builtin_trap();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::span<const std::uint8_t> input(data, size);
  std::size_t newline = 0;
  while (newline < size && data[newline] != '\n') ++newline;
  const std::string_view text(reinterpret_cast<const char*>(data), newline);
  if (const auto number = iio::parseSysfsNumber(text); number && !std::isfinite(*number))
    __builtin_trap();
  const auto type = iio::parseScanType(text);
  if (!type || newline + 1 >= size) return 0;
  if (type->bits < 1 || type->bits + type->shift > type->storage_bits) __builtin_trap();
  const std::uint8_t indices = data[newline + 1];
  const int first = indices & 3, ts = (indices >> 2) & 3;
  const auto s64 = iio::parseScanType("le:s64/64>>0").value();
  const iio::ScanChannel channels[] = {{first, *type, iio::ChannelRole::kRateX},
                                       {first + 1, *type, iio::ChannelRole::kRateY},
                                       {first + 2, *type, iio::ChannelRole::kRateZ},
                                       {ts == 0 ? 9 : first + 2 + ts, s64, iio::ChannelRole::kTimestamp}};
  const auto layout = iio::computeLayout(channels);
  if (!layout) return 0;
  if (layout->scan_bytes == 0 || layout->scan_bytes % 8 != 0 ||
      layout->timestamp.offset + 8 > layout->scan_bytes)
    __builtin_trap();
  decodeAll(input.subspan(newline + 2), *layout);
  return 0;
}
