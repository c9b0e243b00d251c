#include "omnipose/config_error.hpp"

#include "common/problem_list.hpp"

namespace omnipose {

namespace {

std::vector<std::string> escaped(std::vector<std::string> problems) {
  for (auto& p : problems) p = detail::escapeControl(p);
  return problems;
}

}  // namespace

ConfigError ConfigError::listing(const std::string& heading, std::vector<std::string> problems) {
  const std::string what = heading + ":\n  " + detail::joinProblems(problems);
  return ConfigError(what, std::move(problems));
}

ConfigError::ConfigError(const std::string& problem)
    : ConfigError(detail::escapeControl(problem), {problem}) {}

ConfigError::ConfigError(const std::string& what, std::vector<std::string> problems)
    : std::runtime_error(what), problems_(escaped(std::move(problems))) {}

}  // namespace omnipose
