#include "io/text_records.hpp"

#include <cctype>
#include <charconv>

namespace omnipose::io {

std::vector<TextRecord> splitRecords(std::string_view text) {
  std::vector<TextRecord> records;
  int line_no = 0;
  while (!text.empty()) {
    const std::size_t end = text.find('\n');
    std::string_view line = text.substr(0, end);
    text.remove_prefix(end == std::string_view::npos ? text.size() : end + 1);
    ++line_no;
    TextRecord record{line_no, {}};
    std::size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && (line[i] == ' ' || line[i] == '\t' || line[i] == '\r')) ++i;
      std::size_t j = i;
      while (j < line.size() && line[j] != ' ' && line[j] != '\t' && line[j] != '\r') ++j;
      if (j > i) record.fields.push_back(line.substr(i, j - i));
      i = j;
    }
    if (record.fields.empty() || record.fields.front().front() == '#') continue;
    records.push_back(std::move(record));
  }
  return records;
}

std::optional<double> parseDecimal(std::string_view field) {
  // [+-] digits [. digits] [e [+-] digits], at least one digit in the mantissa.
  std::size_t i = 0;
  const auto digits = [&] {
    const std::size_t start = i;
    while (i < field.size() && std::isdigit(static_cast<unsigned char>(field[i]))) ++i;
    return i - start;
  };
  if (i < field.size() && (field[i] == '+' || field[i] == '-')) ++i;
  std::size_t mantissa = digits();
  if (i < field.size() && field[i] == '.') {
    ++i;
    mantissa += digits();
  }
  if (mantissa == 0) return std::nullopt;
  if (i < field.size() && (field[i] == 'e' || field[i] == 'E')) {
    ++i;
    if (i < field.size() && (field[i] == '+' || field[i] == '-')) ++i;
    if (digits() == 0) return std::nullopt;
  }
  if (i != field.size()) return std::nullopt;
  // from_chars takes no leading '+'.
  const std::string_view number = field.front() == '+' ? field.substr(1) : field;
  double value = 0.0;
  const auto [ptr, ec] = std::from_chars(number.data(), number.data() + number.size(), value,
                                         std::chars_format::general);
  if (ec != std::errc() || ptr != number.data() + number.size()) return std::nullopt;
  return value;
}

}  // namespace omnipose::io
