#pragma once
/// \file iio_scan.hpp
/// The format of the Linux IIO buffered interface's scans (kernel
/// Documentation/ABI/testing/sysfs-bus-iio, scan_elements; driver-api/iio/buffers.rst), pure:
/// no I/O, no allocation. parseScanType() reads a channel's `_type` attribute,
/// computeLayout() places the enabled channels in a scan as the kernel does, decodeScan()
/// turns one scan of bytes into a gyro sample and says whether it can be believed.
///
/// Worked example, a BMI160 (drivers/iio/imu/bmi160) with the gyro and timestamp enabled:
/// in_anglvel_{x,y,z}_index 4, 5, 6, type "le:s16/16>>0"; in_timestamp_index 10, type
/// "le:s64/64>>0". The scan is x at byte 0, y at 2, z at 4, 2 bytes of padding, the
/// timestamp at 8 (aligned to its 8 bytes): 16 bytes. With in_anglvel_scale "0.000266"
/// (±500 deg/s; the kernel rounds 500 deg/s / 32768 = 0.000266316 rad/s to micro units), a
/// raw 1000 is 0.266 rad/s.

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include "omnipose/error.hpp"
#include "omnipose/gyro.hpp"

namespace omnipose::iio {

/// A channel's `_type`: "[be|le]:[s|u]BITS/STORAGEBITS[XREPEAT]>>SHIFT", e.g. "le:s16/16>>0",
/// "be:u12/16>>4", "le:s16/16X3>>0". The value is the `bits` bits above `shift` of the
/// storage word, sign-extended when signed.
struct ScanType {
  bool big_endian = false;
  bool is_signed = false;
  int bits = 0;          ///< significant bits, 1..storage_bits - shift
  int storage_bits = 0;  ///< 8, 16, 32 or 64
  int repeat = 1;        ///< elements of this channel in a scan (X suffix); 1 without one
  int shift = 0;         ///< bits to shift right before masking, < storage_bits

  int storageBytes() const { return storage_bits / 8; }
  /// The smallest and largest raw value the type can hold (the saturation rails).
  std::int64_t minRaw() const;
  std::int64_t maxRaw() const;
};

/// Parses a `_type` value (a trailing newline is allowed). Errors (kInvalidArgument) name the
/// text and what is wrong: an unknown endianness or sign, storage bits other than
/// 8/16/32/64, bits of 0 or beyond the storage less the shift, a repeat of 0, an unsigned
/// 64-bit value (its raw value would not fit the signed 64 bits decoding works in).
Expected<ScanType> parseScanType(std::string_view text);

/// What an enabled channel is to the gyro.
enum class ChannelRole { kRateX, kRateY, kRateZ, kTimestamp, kOther };

/// An enabled scan element: its `_index`, its `_type` and its role.
struct ScanChannel {
  int index = 0;
  ScanType type;
  ChannelRole role = ChannelRole::kOther;
};

/// Where the gyro's fields lie in a scan.
struct ScanLayout {
  struct Field {
    ScanType type;
    std::size_t offset = 0;  ///< bytes from the scan's start
  };
  std::array<Field, 3> rate;  ///< x, y, z
  Field timestamp;            ///< signed 64 bits, nanoseconds
  std::size_t scan_bytes = 0; ///< bytes per scan, padding included
};

/// The kernel's layout (iio_compute_scan_bytes): the enabled channels in increasing `_index`,
/// each at an offset aligned to its storage size, the scan padded to a multiple of the
/// largest. Errors (kUnsupportedFormat): a rate axis or the timestamp missing, a timestamp
/// that is not s64/64, two channels with one index, a repeat above 1 (no gyro uses it), or
/// a scan over 4096 bytes.
Expected<ScanLayout> computeLayout(std::span<const ScanChannel> channels);

/// Raw values to rad/s: rate = (raw + offset) * scale, per axis (x, y, z).
struct RateScale {
  std::array<double, 3> scale{};   ///< rad/s per LSB (`in_anglvel[_x]_scale`)
  std::array<double, 3> offset{};  ///< LSB added before scaling (`in_anglvel[_x]_offset`; 0)
};

/// Why a scan is not used.
enum class ScanVerdict {
  kOk,
  kTimestampZero,       ///< zero or negative: no time (a driver that has not stamped it)
  kTimestampBackwards,  ///< at or before the previous good scan's time
  kSaturated,           ///< a rate axis at its type's rail: the true rate is beyond the range
  kTruncated,           ///< fewer bytes than a scan (a partial read)
};
const char* toString(ScanVerdict verdict);

/// One decoded scan.
struct DecodedScan {
  ScanVerdict verdict = ScanVerdict::kOk;
  std::int64_t timestamp_ns = 0;  ///< the scan's timestamp as stamped
  GyroSample sample;              ///< t = timestamp_ns * 1e-9 s, rate in rad/s (IMU axes)
};

/// Decodes `scan` (layout.scan_bytes bytes; a shorter span is kTruncated and never read)
/// against the previous good scan's timestamp `previous_ns` (0: none yet). The sample is
/// filled whatever the verdict (for messages). Allocation-free, never throws.
DecodedScan decodeScan(std::span<const std::uint8_t> scan, const ScanLayout& layout,
                       const RateScale& scale, std::int64_t previous_ns);

/// The raw value of one field of a scan (bytes at its offset, endianness, shift, mask, sign).
/// `scan` must hold offset + storage bytes.
std::int64_t extractRaw(std::span<const std::uint8_t> scan, const ScanLayout::Field& field);

/// A sysfs number such as "0.000266316\n", "-3", "1.5e-3": plain decimal (a trailing newline or
/// spaces allowed); errors (kInvalidArgument) name the text.
Expected<double> parseSysfsNumber(std::string_view text);

}  // namespace omnipose::iio
