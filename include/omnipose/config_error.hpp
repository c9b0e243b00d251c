#pragma once
/// \file config_error.hpp
/// The one error type of every configuration input read at start-up: calibration.yaml and
/// the lens model files it names, daemon.yaml, synth motion scripts.

#include <stdexcept>
#include <string>
#include <vector>

namespace omnipose {

/// Thrown on an invalid configuration input. problems() holds every problem found, each
/// naming the file and the key (or line); what() is a heading followed by at most 20 of
/// them, one per line, then "and N more". Echoed inputs are shortened and their control
/// characters escaped, so what() is short and never cut by an embedded NUL.
class ConfigError : public std::runtime_error {
 public:
  /// `heading` (e.g. "cal.yaml: invalid calibration"), then the problems one per line.
  static ConfigError listing(const std::string& heading, std::vector<std::string> problems);
  /// A single problem, which is also what().
  explicit ConfigError(const std::string& problem);
  /// `what` as given, with `problems` behind it.
  ConfigError(const std::string& what, std::vector<std::string> problems);

  const std::vector<std::string>& problems() const { return problems_; }

 private:
  std::vector<std::string> problems_;
};

}  // namespace omnipose
