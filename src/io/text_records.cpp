#include "io/text_records.hpp"

#include <cctype>
#include <charconv>

namespace omnipose::io {

namespace {

bool isBlank(char c) { return c == ' ' || c == '\t' || c == '\r'; }

/// Calls `split(line)` (the fields of a line) for every line that is neither blank nor a
/// comment; the records of those that give fields.
template <typename Split>
std::vector<TextRecord> dataRecords(std::string_view text, Split split) {
  std::vector<TextRecord> records;
  int line_no = 0;
  while (!text.empty()) {
    const std::size_t end = text.find('\n');
    const std::string_view line = text.substr(0, end);
    text.remove_prefix(end == std::string_view::npos ? text.size() : end + 1);
    ++line_no;
    std::size_t first = 0;
    while (first < line.size() && isBlank(line[first])) ++first;
    if (first == line.size() || line[first] == '#') continue;
    records.push_back({line_no, split(line)});
  }
  return records;
}

}  // namespace

std::vector<TextRecord> splitRecords(std::string_view text) {
  return dataRecords(text, [](std::string_view line) {
    std::vector<std::string_view> fields;
    std::size_t i = 0;
    while (i < line.size()) {
      while (i < line.size() && isBlank(line[i])) ++i;
      std::size_t j = i;
      while (j < line.size() && !isBlank(line[j])) ++j;
      if (j > i) fields.push_back(line.substr(i, j - i));
      i = j;
    }
    return fields;
  });
}

std::vector<TextRecord> splitCsvRecords(std::string_view text) {
  return dataRecords(text, [](std::string_view line) {
    std::vector<std::string_view> fields;
    while (true) {
      const std::size_t comma = line.find(',');
      std::string_view field = line.substr(0, comma);
      while (!field.empty() && isBlank(field.front())) field.remove_prefix(1);
      while (!field.empty() && isBlank(field.back())) field.remove_suffix(1);
      fields.push_back(field);
      if (comma == std::string_view::npos) return fields;
      line.remove_prefix(comma + 1);
    }
  });
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
