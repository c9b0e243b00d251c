#include "omnipose/io/gyro.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <optional>
#include <stdexcept>

#include "common/format.hpp"
#include "common/problem_list.hpp"
#include "io/text_records.hpp"
#include "omnipose/file_io.hpp"

namespace omnipose {
namespace {

constexpr std::array<std::string_view, 4> kColumns = {"t", "wx", "wy", "wz"};

/// Where t, wx, wy and wz stand in the header's fields; throws naming what is wrong.
std::array<std::size_t, 4> columnsOf(const std::vector<std::string_view>& header,
                                     const std::string& where) {
  std::array<std::size_t, 4> at{};
  for (std::size_t c = 0; c < kColumns.size(); ++c) {
    const auto it = std::find(header.begin(), header.end(), kColumns[c]);
    if (it == header.end())
      throw std::runtime_error(where + "the header must name the columns t, wx, wy and wz (" +
                               std::string(kColumns[c]) + " is missing)");
    at[c] = static_cast<std::size_t>(it - header.begin());
  }
  std::vector<std::string_view> sorted = header;
  std::sort(sorted.begin(), sorted.end());
  if (const auto twice = std::adjacent_find(sorted.begin(), sorted.end()); twice != sorted.end())
    throw std::runtime_error(where + "column '" + detail::shown(*twice) + "' is named twice");
  return at;
}

/// The timing figures of `r.samples` (at least one sample, in order).
void measureTiming(GyroRecording& r) {
  if (r.samples.size() < 2) return;
  std::vector<double> intervals;
  intervals.reserve(r.samples.size() - 1);
  for (std::size_t k = 1; k < r.samples.size(); ++k)
    intervals.push_back(r.samples[k].t - r.samples[k - 1].t);
  r.longest_gap_s = *std::max_element(intervals.begin(), intervals.end());
  std::vector<double> sorted = intervals;
  const auto mid = sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2);
  std::nth_element(sorted.begin(), mid, sorted.end());
  r.median_interval_s = *mid;
  r.gaps = static_cast<int>(std::count_if(intervals.begin(), intervals.end(), [&](double d) {
    return d > kGyroGapIntervals * r.median_interval_s;
  }));
}

}  // namespace

GyroRecording parseGyroCsv(std::string_view text, const std::string& origin) {
  GyroRecording r;
  std::optional<std::array<std::size_t, 4>> columns;
  std::size_t field_count = 0;
  for (const io::TextRecord& record : io::splitCsvRecords(text)) {
    const auto where = [&] { return origin + ":" + std::to_string(record.line) + ": "; };
    const std::vector<std::string_view>& fields = record.fields;
    if (!columns) {
      columns = columnsOf(fields, where());
      field_count = fields.size();
      continue;
    }
    if (fields.size() != field_count)
      throw std::runtime_error(where() + std::to_string(fields.size()) +
                               " fields, the header has " + std::to_string(field_count));
    std::array<double, 4> v{};
    for (std::size_t c = 0; c < kColumns.size(); ++c) {
      const std::string_view field = fields[(*columns)[c]];
      const std::optional<double> x = io::parseDecimal(field);
      if (!x || !std::isfinite(*x))
        throw std::runtime_error(where() + std::string(kColumns[c]) + ": '" +
                                 detail::shown(field) + "' is not a finite decimal number");
      v[c] = *x;
      if (c > 0 && !(std::abs(v[c]) <= kMaxGyroRate))
        throw std::runtime_error(where() + std::string(kColumns[c]) + ": " +
                                 detail::format("%.9g", v[c]) + " rad/s is beyond any gyro's range (" +
                                 detail::format("%g", kMaxGyroRate) + " rad/s)");
    }
    if (!r.samples.empty() && !(v[0] > r.samples.back().t))
      throw std::runtime_error(where() + detail::format("t %.9g s is not after the sample before "
                                                        "it (%.9g s): samples out of order or "
                                                        "given twice",
                                                        v[0], r.samples.back().t));
    r.samples.push_back({v[0], Eigen::Vector3d(v[1], v[2], v[3])});
  }
  if (!columns) throw std::runtime_error(origin + ": no header (t,wx,wy,wz) and no samples");
  if (r.samples.empty()) throw std::runtime_error(origin + ": no samples");
  return gyroRecordingOf(std::move(r.samples));
}

GyroRecording gyroRecordingOf(std::vector<GyroSample> samples) {
  if (samples.empty()) throw std::invalid_argument("gyroRecordingOf: no samples");
  for (std::size_t k = 1; k < samples.size(); ++k)
    if (!(samples[k].t > samples[k - 1].t))
      throw std::invalid_argument("gyroRecordingOf: sample " + std::to_string(k) +
                                  " is not after the one before it");
  GyroRecording r;
  r.samples = std::move(samples);
  measureTiming(r);
  return r;
}

std::string formatGyroCsv(std::span<const GyroSample> samples) {
  std::string text = "t,wx,wy,wz\n";
  text.reserve(text.size() + samples.size() * 72);
  for (const GyroSample& s : samples)
    text += detail::format("%.9f,%.9e,%.9e,%.9e\n", s.t, s.rate.x(), s.rate.y(), s.rate.z());
  return text;
}

void writeGyroCsv(const std::filesystem::path& path, std::span<const GyroSample> samples) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path.string() + ": cannot write the gyro recording");
  out << formatGyroCsv(samples);
  if (!out) throw std::runtime_error(path.string() + ": write failed");
}

GyroRecording readGyroCsv(const std::filesystem::path& path) {
  return parseGyroCsv(readTextFileOrThrow(path), path.string());
}

}  // namespace omnipose
