#pragma once
/// \file gyro.hpp
/// A recorded gyro: `imu.csv` in a dataset directory (docs/DESIGN.md section 6).
///
///   t,wx,wy,wz,ax,ay,az
///   12.000000,0.0012,-0.0031,0.2100,0.01,-0.02,9.81
///   12.005000,0.0013,-0.0030,0.2104,0.01,-0.02,9.80
///
/// The first line that is neither blank nor a `#` comment is the header: comma-separated
/// column names, which must include t, wx, wy and wz in any order; other columns (the
/// accelerometer's ax, ay, az, a temperature ...) are allowed and ignored. Each following
/// line is one sample: t in seconds on the IMU's clock, wx, wy, wz the angular rate in rad/s
/// about the IMU's own x, y, z axes. Fields may carry blanks around them; numbers are plain
/// decimals (io/text_records.hpp: no hexadecimal, inf or nan).

#include <filesystem>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "omnipose/gyro.hpp"

namespace omnipose {

/// A gyro recording as read, with what its timing says.
struct GyroRecording {
  std::vector<GyroSample> samples;  ///< in file order, t strictly increasing
  /// Median interval between samples, seconds (1 / the sampling rate); 0 with one sample.
  double median_interval_s = 0.0;
  int gaps = 0;                 ///< intervals longer than kGyroGapIntervals x the median
  double longest_gap_s = 0.0;   ///< the longest interval, seconds (0 with one sample)
};

/// Parses imu.csv text; `origin` (the file's path) starts every message. Throws
/// std::runtime_error "<origin>:<line>: <what>" for: no header, a header without t, wx, wy or
/// wz or naming a column twice, a line whose field count differs from the header's, a
/// field that is not a finite plain decimal number, a time not after the one before it (a
/// sample out of order or given twice), and "<origin>: no samples" for a file without any.
GyroRecording parseGyroCsv(std::string_view text, const std::string& origin);

/// A recording of `samples` (t strictly increasing, at least one) with its timing measured.
/// Throws std::invalid_argument when they are empty or out of order.
GyroRecording gyroRecordingOf(std::vector<GyroSample> samples);

/// The imu.csv text of `samples`: the header `t,wx,wy,wz`, then t to the nanosecond and each
/// rate to 10 significant digits, so parseGyroCsv() reads them back.
std::string formatGyroCsv(std::span<const GyroSample> samples);

/// Writes formatGyroCsv(samples) to `path`; throws std::runtime_error naming the file when it
/// cannot be written.
void writeGyroCsv(const std::filesystem::path& path, std::span<const GyroSample> samples);

/// parseGyroCsv() of the file at `path` (a regular file of at most kMaxTextFileBytes);
/// throws std::runtime_error naming the file when it cannot be read.
GyroRecording readGyroCsv(const std::filesystem::path& path);

}  // namespace omnipose
