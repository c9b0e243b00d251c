#pragma once
/// \file text_records.hpp
/// The line-oriented text formats of a dataset (timestamps.txt, TUM trajectories, imu.csv):
/// blank lines and lines whose first non-blank character is '#' are skipped, the others
/// split on blanks and tabs, or on commas.
/// Numbers are plain decimals (`12`, `-0.5`, `1.5e9`): hexadecimal floats, `inf` and
/// `nan`, which the C library would also read, are refused.

#include <cstddef>
#include <optional>
#include <string_view>
#include <vector>

namespace omnipose::io {

/// One data line: its number (1-based) and its fields.
struct TextRecord {
  int line = 0;
  std::vector<std::string_view> fields;
};

/// The data lines of `text` (views into it).
std::vector<TextRecord> splitRecords(std::string_view text);

/// The data lines of comma-separated `text` (views into it): every field with the blanks
/// around it removed, empty fields kept ("1,,2" has three fields).
std::vector<TextRecord> splitCsvRecords(std::string_view text);

/// `field` as a plain decimal number; nullopt for anything else.
std::optional<double> parseDecimal(std::string_view field);

}  // namespace omnipose::io
