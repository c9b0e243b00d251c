#pragma once
/// The one YAML reader of the configuration inputs (calibration.yaml, daemon.yaml, synth
/// motion scripts; private to the libraries). It reads typed values out of maps and collects
/// every problem, each "<origin>: <key path>: <what>": values that cannot be read as the
/// field's type, unknown keys, keys given twice (in any map, at any depth), strings longer
/// than kMaxStringBytes, numbers out of range. Echoed keys and values are shortened and
/// their control characters escaped (detail::shown).

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include "common/named_values.hpp"
#include "common/problem_list.hpp"

namespace omnipose::detail {

/// Longest string value accepted, bytes.
inline constexpr std::size_t kMaxStringBytes = 4096;
/// Most nodes (aliases counted each time they are used) and deepest nesting the key check
/// walks; a document beyond either is a problem.
inline constexpr std::size_t kMaxYamlNodes = 100000;
inline constexpr int kMaxYamlDepth = 100;

/// How a message names the type a value was read as.
template <typename T>
constexpr const char* yamlTypeName() {
  if constexpr (std::is_same_v<T, bool>) return "true or false";
  else if constexpr (std::is_integral_v<T> && std::is_unsigned_v<T>) return "a non-negative integer";
  else if constexpr (std::is_integral_v<T>) return "an integer";
  else if constexpr (std::is_floating_point_v<T>) return "a number";
  else if constexpr (std::is_same_v<T, std::vector<int>>) return "a list of integers";
  else return "a string";
}

/// A node as a message echoes it: a scalar's text, a list or map in flow style; shortened
/// to kMaxEchoedChars with control characters escaped (however large the node is).
std::string echoed(const YAML::Node& node);

/// Parses YAML text; throws ConfigError "<origin>: not valid YAML: ..." on a syntax error.
YAML::Node loadYaml(const std::string& text, const std::string& origin);

class YamlReader {
 public:
  enum class Need { kOptional, kRequired };

  explicit YamlReader(std::string origin) : origin_(std::move(origin)) {}

  const std::string& origin() const { return origin_; }
  /// Adds "<origin>: <path>: <what>".
  void problem(std::string_view path, std::string_view what);
  /// Adds "<origin>: <what>" (a problem that names its field itself, e.g. from validate()).
  void add(std::string_view what);
  std::vector<std::string>& problems() { return problems_; }

  /// `path`.`key` with the key shown as messages show inputs; "key" at the top level.
  static std::string join(std::string_view path, std::string_view key);

  /// Reports every key given more than once in any map of the document, at every level
  /// ("<path>.<key>: given twice, lines 4 and 9"), and a document larger or deeper than
  /// kMaxYamlNodes / kMaxYamlDepth.
  void checkDuplicateKeys(const YAML::Node& root);

  /// Whether `node` (at `path`, "" = the document) is a map; reports it when not, and
  /// reports keys that are not plain names or not in `known` ("<path>.<key>: <unknown>").
  bool checkMap(const YAML::Node& node, std::string_view path, const std::vector<std::string>& known,
                std::string_view unknown = "unknown key");

  /// Reads map[key] as one of the names of `names` into `value` (left as it is when absent,
  /// "missing" when required). A name not in the table is a problem "'<name>' is not a, b or
  /// c" and leaves `value` as it is. `name`, when given, receives the text read (known or
  /// not) for later messages. Returns whether a known name was read.
  template <typename Value, std::size_t N>
  bool getNamed(const YAML::Node& map, std::string_view path, const std::string& key,
                const Named<Value> (&names)[N], Value& value, Need need = Need::kOptional,
                std::string* name = nullptr) {
    std::string text = nameOf(names, value, "");
    const bool given = get(map, path, key, text, need);
    if (name) *name = text;
    if (!given) return false;
    if (const auto named = valueNamed(names, text)) {
      value = *named;
      return true;
    }
    problem(join(path, key), "'" + shown(text) + "' is not " + nameList(names));
    return false;
  }

  /// Reads map[key] into `value` (left as it is when absent, "missing" when required):
  /// "cannot read '<value>' as <type>", a string over kMaxStringBytes, a number that is
  /// not finite are problems. Returns whether a value was read.
  template <typename T>
  bool get(const YAML::Node& map, std::string_view path, const std::string& key, T& value,
           Need need = Need::kOptional) {
    const YAML::Node node = child(map, key);
    const std::string where = join(path, key);
    if (!node) {
      if (need == Need::kRequired) problem(where, "missing");
      return false;
    }
    if constexpr (std::is_same_v<T, std::string>) {
      if (node.IsScalar() && node.Scalar().size() > kMaxStringBytes) {
        problem(where, "'" + echoed(node) + "' is longer than " + std::to_string(kMaxStringBytes) +
                           " bytes");
        return false;
      }
    }
    try {
      const T v = node.template as<T>();
      if constexpr (std::is_floating_point_v<T>) {
        if (!std::isfinite(v)) {
          problem(where, "must be a finite number, not '" + echoed(node) + "'");
          return false;
        }
      }
      value = v;
      return true;
    } catch (const YAML::Exception&) {
      problem(where, "cannot read '" + echoed(node) + "' as " + yamlTypeName<T>());
      return false;
    }
  }

  /// Reads map[key], a list of `count` finite numbers (a list of lists is read row by row).
  bool getNumbers(const YAML::Node& map, std::string_view path, const std::string& key,
                  std::size_t count, std::vector<double>& out, Need need = Need::kRequired);
  /// Reads map[key], one number (lo = hi) or a list [lo, hi].
  bool getInterval(const YAML::Node& map, std::string_view path, const std::string& key,
                   double& lo, double& hi);

  /// detail::checkRange, the problem prefixed with the origin.
  template <typename T>
  void range(T value, std::string_view field, T lo, T hi, std::string_view unit = {},
             bool open_below = false) {
    std::vector<std::string> found;
    checkRange(found, field, value, lo, hi, unit, open_below);
    for (const auto& p : found) add(p);
  }

  /// Throws ConfigError "<origin>: <heading>:" listing the problems, if there are any.
  void throwIfProblems(std::string_view heading) const;

  /// map[key] when `map` is a map holding it, else an invalid node.
  static YAML::Node child(const YAML::Node& map, const std::string& key);

 private:
  void walk(const YAML::Node& node, const std::string& path, int depth, std::size_t& budget);

  std::string origin_;
  std::vector<std::string> problems_;
};

}  // namespace omnipose::detail
