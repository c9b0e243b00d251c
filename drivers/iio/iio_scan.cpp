#include "iio/iio_scan.hpp"

#include <algorithm>
#include <charconv>
#include <cmath>

namespace omnipose::iio {
namespace {

/// Reads a decimal integer at the front of `text`, advancing it; false when there is none.
bool takeInt(std::string_view& text, int& value) {
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end == text.data()) return false;
  text.remove_prefix(static_cast<std::size_t>(end - text.data()));
  return true;
}

bool takePrefix(std::string_view& text, std::string_view prefix) {
  if (!text.starts_with(prefix)) return false;
  text.remove_prefix(prefix.size());
  return true;
}

std::string_view trimmed(std::string_view text) {
  while (!text.empty() && (text.back() == '\n' || text.back() == ' ' || text.back() == '\t'))
    text.remove_suffix(1);
  while (!text.empty() && (text.front() == ' ' || text.front() == '\t')) text.remove_prefix(1);
  return text;
}

/// The endianness, sign, bits and storage bits: "le:s16/16".
bool parseHead(std::string_view& s, ScanType& t) {
  if (takePrefix(s, "be:")) t.big_endian = true;
  else if (!takePrefix(s, "le:")) return false;
  if (takePrefix(s, "s")) t.is_signed = true;
  else if (!takePrefix(s, "u")) return false;
  return takeInt(s, t.bits) && takePrefix(s, "/") && takeInt(s, t.storage_bits);
}

/// The optional repeat and the shift: "X3>>0".
bool parseTail(std::string_view& s, ScanType& t) {
  if (takePrefix(s, "X") && !takeInt(s, t.repeat)) return false;
  return takePrefix(s, ">>") && takeInt(s, t.shift) && s.empty();
}

const char* checkType(const ScanType& t) {
  if (t.storage_bits != 8 && t.storage_bits != 16 && t.storage_bits != 32 && t.storage_bits != 64)
    return "storage bits must be 8, 16, 32 or 64";
  if (t.shift < 0 || t.shift >= t.storage_bits) return "the shift must be below the storage bits";
  if (t.bits < 1 || t.bits > t.storage_bits - t.shift)
    return "the bits must be 1 to the storage bits less the shift";
  if (t.repeat < 1) return "a repeat must be at least 1";
  if (!t.is_signed && t.bits == 64) return "an unsigned 64-bit value is not supported";
  return nullptr;
}

std::size_t alignUp(std::size_t value, std::size_t alignment) {
  return (value + alignment - 1) / alignment * alignment;
}

int axisOf(ChannelRole role) {
  switch (role) {
    case ChannelRole::kRateX: return 0;
    case ChannelRole::kRateY: return 1;
    case ChannelRole::kRateZ: return 2;
    default: return -1;
  }
}

/// Checks the channel set before the layout: indices distinct, no repeat, the four fields.
Expected<void> checkChannels(std::span<const ScanChannel> sorted) {
  std::array<bool, 4> seen{};  // x, y, z, timestamp
  for (std::size_t i = 0; i < sorted.size(); ++i) {
    const ScanChannel& c = sorted[i];
    if (i > 0 && sorted[i - 1].index == c.index)
      return fail(ErrorCode::kUnsupportedFormat, "two enabled channels have scan index %d", c.index);
    if (c.type.repeat != 1)
      return fail(ErrorCode::kUnsupportedFormat,
                  "the channel of scan index %d repeats %d times in a scan (not supported)",
                  c.index, c.type.repeat);
    const int axis = axisOf(c.role);
    if (axis >= 0) seen[static_cast<std::size_t>(axis)] = true;
    if (c.role == ChannelRole::kTimestamp) seen[3] = true;
  }
  static constexpr const char* kNames[] = {"in_anglvel_x", "in_anglvel_y", "in_anglvel_z",
                                           "in_timestamp"};
  for (std::size_t k = 0; k < seen.size(); ++k) {
    if (!seen[k]) return fail(ErrorCode::kUnsupportedFormat, "%s is not in the scan", kNames[k]);
  }
  return {};
}

}  // namespace

std::int64_t ScanType::minRaw() const {
  if (!is_signed) return 0;
  return bits >= 64 ? INT64_MIN : -(std::int64_t{1} << (bits - 1));
}

std::int64_t ScanType::maxRaw() const {
  // Unsigned: 2^bits - 1, at most 2^63 - 1 (parseScanType() refuses an unsigned 64-bit type).
  const int magnitude_bits = is_signed ? bits - 1 : bits;
  if (magnitude_bits >= 63) return INT64_MAX;
  return static_cast<std::int64_t>((std::uint64_t{1} << magnitude_bits) - 1);
}

Expected<ScanType> parseScanType(std::string_view text) {
  const std::string_view original = trimmed(text);
  std::string_view s = original;
  ScanType t;
  if (!parseHead(s, t) || !parseTail(s, t)) {
    return fail(ErrorCode::kInvalidArgument,
                "scan type \"%.*s\" is not [be|le]:[s|u]BITS/STORAGE[XREPEAT]>>SHIFT",
                static_cast<int>(std::min<std::size_t>(original.size(), 64)), original.data());
  }
  if (const char* why = checkType(t)) {
    return fail(ErrorCode::kInvalidArgument, "scan type \"%.*s\": %s",
                static_cast<int>(std::min<std::size_t>(original.size(), 64)), original.data(), why);
  }
  return t;
}

Expected<ScanLayout> computeLayout(std::span<const ScanChannel> channels) {
  constexpr std::size_t kMaxChannels = 64, kMaxScanBytes = 4096;
  if (channels.size() > kMaxChannels)
    return fail(ErrorCode::kUnsupportedFormat, "%zu channels enabled (at most 64)", channels.size());
  std::array<ScanChannel, kMaxChannels> sorted;
  std::copy(channels.begin(), channels.end(), sorted.begin());
  const std::span<ScanChannel> order(sorted.data(), channels.size());
  std::sort(order.begin(), order.end(),
            [](const ScanChannel& a, const ScanChannel& b) { return a.index < b.index; });
  if (auto ok = checkChannels(order); !ok) return std::unexpected(ok.error());
  ScanLayout layout;
  std::size_t bytes = 0, largest = 1;
  for (const ScanChannel& c : order) {
    // Each element aligned to its own size (storage bytes x repeat; repeat is 1 here).
    const auto size = static_cast<std::size_t>(c.type.storageBytes());
    bytes = alignUp(bytes, size);
    const ScanLayout::Field field{c.type, bytes};
    if (const int axis = axisOf(c.role); axis >= 0) layout.rate[static_cast<std::size_t>(axis)] = field;
    if (c.role == ChannelRole::kTimestamp) layout.timestamp = field;
    bytes += size;
    largest = std::max(largest, size);
  }
  const ScanType& ts = layout.timestamp.type;
  if (!ts.is_signed || ts.storage_bits != 64 || ts.bits != 64 || ts.shift != 0)
    return fail(ErrorCode::kUnsupportedFormat, "in_timestamp is not a signed 64-bit value");
  layout.scan_bytes = alignUp(bytes, largest);
  if (layout.scan_bytes > kMaxScanBytes)
    return fail(ErrorCode::kUnsupportedFormat, "a scan of %zu bytes (at most 4096)", layout.scan_bytes);
  return layout;
}

std::int64_t extractRaw(std::span<const std::uint8_t> scan, const ScanLayout::Field& field) {
  const int n = field.type.storageBytes();
  std::uint64_t word = 0;
  for (int i = 0; i < n; ++i) {
    // Byte i of the value, least significant first.
    const std::size_t at = field.offset + static_cast<std::size_t>(field.type.big_endian ? n - 1 - i : i);
    word |= std::uint64_t{scan[at]} << (8 * i);
  }
  word >>= field.type.shift;
  const int bits = field.type.bits;
  if (bits < 64) {
    word &= (std::uint64_t{1} << bits) - 1;
    if (field.type.is_signed && (word >> (bits - 1)) != 0) word |= ~((std::uint64_t{1} << bits) - 1);
  }
  return static_cast<std::int64_t>(word);
}

const char* toString(ScanVerdict verdict) {
  switch (verdict) {
    case ScanVerdict::kOk: return "ok";
    case ScanVerdict::kTimestampZero: return "timestamp zero or negative";
    case ScanVerdict::kTimestampBackwards: return "timestamp not after the previous scan's";
    case ScanVerdict::kSaturated: return "a rate at the sensor's rail (beyond its range)";
    case ScanVerdict::kTruncated: return "a partial scan";
  }
  return "unknown";
}

DecodedScan decodeScan(std::span<const std::uint8_t> scan, const ScanLayout& layout,
                       const RateScale& scale, std::int64_t previous_ns) {
  DecodedScan out;
  if (layout.scan_bytes == 0 || scan.size() < layout.scan_bytes) {
    out.verdict = ScanVerdict::kTruncated;
    return out;
  }
  out.timestamp_ns = extractRaw(scan, layout.timestamp);
  out.sample.t = static_cast<double>(out.timestamp_ns) * 1e-9;
  bool saturated = false;
  for (std::size_t k = 0; k < 3; ++k) {
    const ScanLayout::Field& f = layout.rate[k];
    const std::int64_t raw = extractRaw(scan, f);
    saturated = saturated || raw <= f.type.minRaw() || raw >= f.type.maxRaw();
    // rate = (raw + offset) * scale (sysfs-bus-iio, _offset and _scale).
    out.sample.rate[static_cast<Eigen::Index>(k)] =
        (static_cast<double>(raw) + scale.offset[k]) * scale.scale[k];
  }
  if (out.timestamp_ns <= 0) out.verdict = ScanVerdict::kTimestampZero;
  else if (out.timestamp_ns <= previous_ns) out.verdict = ScanVerdict::kTimestampBackwards;
  else if (saturated) out.verdict = ScanVerdict::kSaturated;
  return out;
}

Expected<double> parseSysfsNumber(std::string_view text) {
  const std::string_view s = trimmed(text);
  double value = 0.0;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), value);
  if (s.empty() || ec != std::errc() || end != s.data() + s.size() || !std::isfinite(value)) {
    return fail(ErrorCode::kInvalidArgument, "\"%.*s\" is not a number",
                static_cast<int>(std::min<std::size_t>(s.size(), 64)), s.data());
  }
  return value;
}

}  // namespace omnipose::iio
