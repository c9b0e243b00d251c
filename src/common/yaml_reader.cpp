#include "common/yaml_reader.hpp"

#include <map>

#include "omnipose/config_error.hpp"

namespace omnipose::detail {
namespace {

/// Appends `node` in flow style to `out`, stopping once `out` holds more than `limit` bytes.
void flow(const YAML::Node& node, std::string& out, std::size_t limit) {
  const auto append = [&](std::string_view text) {
    if (out.size() <= limit) out.append(text.substr(0, limit + 1 - out.size()));
  };
  switch (node.Type()) {
    case YAML::NodeType::Scalar: append(node.Scalar()); return;
    case YAML::NodeType::Sequence:
    case YAML::NodeType::Map: {
      const bool map = node.IsMap();
      append(map ? "{" : "[");
      bool first = true;
      for (const auto& item : node) {
        if (out.size() > limit) return;
        if (!first) append(", ");
        first = false;
        if (map) {
          flow(item.first, out, limit);
          append(": ");
          flow(item.second, out, limit);
        } else {
          flow(item, out, limit);
        }
      }
      append(map ? "}" : "]");
      return;
    }
    case YAML::NodeType::Null: append("~"); return;
    case YAML::NodeType::Undefined: return;
  }
}

}  // namespace

std::string echoed(const YAML::Node& node) {
  if (node.IsScalar()) return shown(node.Scalar());
  std::string text;
  flow(node, text, kMaxEchoedChars);
  if (text.size() <= kMaxEchoedChars) return escapeControl(text);
  return escapeControl(std::string_view(text).substr(0, kMaxEchoedChars)) + "...";
}

YAML::Node loadYaml(const std::string& text, const std::string& origin) {
  try {
    return YAML::Load(text);
  } catch (const YAML::Exception& e) {
    const std::string problem = origin + ": not valid YAML: " + shown(e.what());
    throw ConfigError(problem);
  }
}

void YamlReader::problem(std::string_view path, std::string_view what) {
  std::string p = origin_;
  p += ": ";
  p += path.empty() ? std::string_view("(document)") : path;
  p += ": ";
  p += what;
  problems_.push_back(std::move(p));
}

void YamlReader::add(std::string_view what) {
  problems_.push_back(origin_ + ": " + std::string(what));
}

std::string YamlReader::join(std::string_view path, std::string_view key) {
  return path.empty() ? shown(key) : std::string(path) + "." + shown(key);
}

YAML::Node YamlReader::child(const YAML::Node& map, const std::string& key) {
  if (!map || !map.IsMap()) return YAML::Node(YAML::NodeType::Undefined);
  return map[key];
}

void YamlReader::checkDuplicateKeys(const YAML::Node& root) {
  std::size_t budget = kMaxYamlNodes;
  walk(root, "", 0, budget);
  if (budget == 0)
    problem("", "more than " + std::to_string(kMaxYamlNodes) +
                    " nodes (aliases counted where they are used)");
}

void YamlReader::walk(const YAML::Node& node, const std::string& path, int depth,
                      std::size_t& budget) {
  if (budget == 0) return;
  --budget;
  if (depth > kMaxYamlDepth) {
    problem(path, "nested deeper than " + std::to_string(kMaxYamlDepth) + " levels");
    budget = 0;
    return;
  }
  if (node.IsSequence()) {
    std::size_t i = 0;
    for (const auto& item : node) {
      if (budget == 0) return;
      walk(item, path + "[" + std::to_string(i++) + "]", depth + 1, budget);
    }
  } else if (node.IsMap()) {
    std::map<std::string, int, std::less<>> first_line;
    for (const auto& kv : node) {
      if (budget == 0) return;
      if (!kv.first.IsScalar()) continue;  // checkMap reports it
      const std::string& key = kv.first.Scalar();
      const int line = kv.first.Mark().line + 1;
      const auto [it, fresh] = first_line.emplace(key, line);
      if (!fresh)
        problem(join(path, key), "given twice, lines " + std::to_string(it->second) + " and " +
                                     std::to_string(line));
      walk(kv.second, join(path, key), depth + 1, budget);
    }
  }
}

bool YamlReader::checkMap(const YAML::Node& node, std::string_view path,
                          const std::vector<std::string>& known, std::string_view unknown) {
  if (!node.IsMap()) {
    problem(path, "must be a map");
    return false;
  }
  for (const auto& kv : node) {
    if (!kv.first.IsScalar()) {
      problem(path, "keys must be plain names, not '" + echoed(kv.first) + "'");
      continue;
    }
    const std::string& key = kv.first.Scalar();
    bool found = false;
    for (const auto& k : known) found = found || k == key;
    if (!found) problem(join(path, key), unknown);
  }
  return true;
}

bool YamlReader::getNumbers(const YAML::Node& map, std::string_view path, const std::string& key,
                            std::size_t count, std::vector<double>& out, Need need) {
  const YAML::Node node = child(map, key);
  const std::string where = join(path, key);
  if (!node) {
    if (need == Need::kRequired) problem(where, "missing");
    return false;
  }
  std::vector<double> values;
  const auto take = [&](const YAML::Node& n) {
    if (values.size() >= count) return false;
    try {
      values.push_back(n.as<double>());
      return std::isfinite(values.back());
    } catch (const YAML::Exception&) {
      return false;
    }
  };
  bool ok = node.IsSequence();
  for (std::size_t i = 0; ok && i < node.size(); ++i) {
    if (node[i].IsSequence()) {
      for (std::size_t j = 0; ok && j < node[i].size(); ++j) ok = take(node[i][j]);
    } else {
      ok = take(node[i]);
    }
  }
  if (!ok || values.size() != count) {
    problem(where, "must be a list of " + std::to_string(count) + " finite numbers");
    return false;
  }
  out = std::move(values);
  return true;
}

bool YamlReader::getInterval(const YAML::Node& map, std::string_view path, const std::string& key,
                             double& lo, double& hi) {
  const YAML::Node node = child(map, key);
  if (!node) return false;
  try {
    if (node.IsSequence() && node.size() == 2) {
      lo = node[0].as<double>();
      hi = node[1].as<double>();
    } else {
      lo = hi = node.as<double>();
    }
    return true;
  } catch (const YAML::Exception&) {
    problem(join(path, key), "must be a number or a list [min, max]");
    return false;
  }
}

void YamlReader::throwIfProblems(std::string_view heading) const {
  if (problems_.empty()) return;
  throw ConfigError::listing(origin_ + ": " + std::string(heading), problems_);
}

}  // namespace omnipose::detail
