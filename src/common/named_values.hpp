#pragma once
/// \file named_values.hpp
/// The names of a setting's values, written once for both reading and printing it (private to
/// the libraries and programs): a table of {value, name} pairs.
///
///   constexpr detail::Named<UpCue> kUpCues[] = {{UpCue::kBright, "bright"}, ...};
///   detail::nameOf(kUpCues, UpCue::kDark)     -> "dark"
///   detail::valueNamed(kUpCues, "none")       -> UpCue::kNone (none for an unknown name)
///   detail::nameList(kUpCues)                 -> "bright, dark or none" (for error messages)

#include <cstddef>
#include <optional>
#include <string>
#include <string_view>

namespace omnipose::detail {

template <typename Value>
struct Named {
  Value value;
  const char* name;
};

/// The name of `value`, or `unknown` when the table has no entry for it.
template <typename Value, std::size_t N>
constexpr const char* nameOf(const Named<Value> (&names)[N], Value value,
                             const char* unknown = "?") {
  for (const Named<Value>& n : names) {
    if (n.value == value) return n.name;
  }
  return unknown;
}

/// The value called `name` (exactly: case matters), none when no entry has that name.
template <typename Value, std::size_t N>
constexpr std::optional<Value> valueNamed(const Named<Value> (&names)[N], std::string_view name) {
  for (const Named<Value>& n : names) {
    if (name == n.name) return n.value;
  }
  return std::nullopt;
}

/// The names in table order as a message lists them: "a, b or c".
template <typename Value, std::size_t N>
std::string nameList(const Named<Value> (&names)[N]) {
  std::string list;
  for (std::size_t i = 0; i < N; ++i) {
    list += i == 0 ? "" : (i + 1 == N ? " or " : ", ");
    list += names[i].name;
  }
  return list;
}

}  // namespace omnipose::detail
