#pragma once
/// \file cli.hpp
/// The command line of every omnipose program, one way (CLI11):
///   - `-h, --help`: a "usage: NAME ..." line, the description, every option with its units,
///     an optional footer; printed to stdout, exit code 0;
///   - `--version`: "NAME VERSION" (OMNIPOSE_VERSION, from CMake's PROJECT_VERSION), exit 0;
///   - a usage error (unknown flag, missing or malformed value, missing required option,
///     or a semantic check of the program's own): "NAME: MESSAGE" naming the flag, and a
///     hint to --help, on stderr, exit code 2 (kUsageExitCode).
/// An option given twice keeps its last value (as the hand-written parsers did); a failure
/// of the program's work is "NAME: MESSAGE" on stderr, exit code 1 (kFailureExitCode).
/// Every program's main() is runMain (below):
///
///   struct Args { std::vector<std::string> files; std::string json; };
///   void addOptions(CLI::App& app, Args& a) {
///     app.add_option("FILES", a.files, "GT.tum EST.tum ...")->required();
///     app.add_option("--json", a.json, "results as JSON")->type_name("OUT.json");
///   }
///   int main(int argc, char** argv) {
///     return omnipose::tools::runMain<Args>(
///         argc, argv, {"omnipose-eval", "usage: omnipose-eval GT.tum EST.tum ...",
///                      "Scores estimated trajectories against ground truth."},
///         addOptions, [](omnipose::tools::Cli& cli, const Args& a) { return score(a); });
///   }

#include <CLI/CLI.hpp>

#include <algorithm>
#include <cstdio>
#include <exception>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "omnipose_version.hpp"

namespace omnipose::tools {

/// Exit code of every command-line mistake, in every program.
inline constexpr int kUsageExitCode = 2;
/// Exit code of a program whose work failed (an unreadable file, a failed calibration ...).
inline constexpr int kFailureExitCode = 1;

/// The project's version, as `--version` prints it.
inline constexpr const char* kVersion = OMNIPOSE_VERSION;

/// Help text: our own usage line(s) instead of CLI11's "Usage: NAME [OPTIONS]".
class HelpFormatter : public CLI::Formatter {
 public:
  explicit HelpFormatter(std::string usage) : usage_(std::move(usage)) { column_width(28); }
  /// The usage line(s) first, then the description, then the options.
  std::string make_usage(const CLI::App* app, std::string) const override {
    std::string text = usage_.empty() || usage_.back() == '\n' ? usage_ : usage_ + "\n";
    if (const std::string d = app->get_description(); !d.empty()) {
      text += "\n" + d + (d.back() == '\n' ? "" : "\n");
    }
    return text;
  }
  std::string make_description(const CLI::App*) const override { return {}; }
  /// Option descriptions wrapped to fit 80 columns (CLI11 indents the continuation lines).
  std::string make_option_desc(const CLI::Option* opt) const override {
    const std::string text = CLI::Formatter::make_option_desc(opt);
    const std::size_t width = 80 - std::min<std::size_t>(get_column_width(), 60);
    std::string out, line;
    std::size_t start = 0;
    while (start < text.size()) {
      std::size_t end = text.find(' ', start);
      if (end == std::string::npos) end = text.size();
      const std::string word = text.substr(start, end - start);
      if (!line.empty() && line.size() + 1 + word.size() > width) {
        out += line + "\n";
        line.clear();
      }
      line += (line.empty() ? "" : " ") + word;
      start = end + 1;
    }
    return out + line;
  }

 private:
  std::string usage_;
};

class Cli {
 public:
  /// `name`: the program as it is installed; `usage`: the synopsis ("usage: NAME ..."), one
  /// or more lines; `description`: what the program does (after the usage line in --help).
  Cli(std::string name, std::string usage, std::string description = "")
      : name_(std::move(name)), app_(std::move(description), name_) {
    app_.formatter(std::make_shared<HelpFormatter>(std::move(usage)));
    app_.set_version_flag("--version", name_ + " " + kVersion,
                          "print the program's name and version and exit");
    app_.get_help_ptr()->description("print this text and exit");
    app_.option_defaults()->multi_option_policy(CLI::MultiOptionPolicy::TakeLast);
  }
  Cli(const Cli&) = delete;
  Cli& operator=(const Cli&) = delete;

  CLI::App& app() { return app_; }
  const CLI::App& app() const { return app_; }
  const std::string& name() const { return name_; }

  /// Parses the command line. nullopt: go on; otherwise the program returns this exit code
  /// at once (0 after --help or --version, kUsageExitCode after a usage error, which has
  /// been printed).
  std::optional<int> parse(int argc, const char* const* argv) {
    try {
      app_.parse(argc, argv);
      return std::nullopt;
    } catch (const CLI::CallForHelp&) {
      std::fputs(app_.help().c_str(), stdout);
      return 0;
    } catch (const CLI::CallForAllHelp&) {
      std::fputs(app_.help("", CLI::AppFormatMode::All).c_str(), stdout);
      return 0;
    } catch (const CLI::CallForVersion& e) {
      std::printf("%s\n", e.what());
      return 0;
    } catch (const CLI::ParseError& e) {
      // CLI11 checks required options before it complains about arguments it did not
      // expect; the unknown flag is the mistake to name (it may be a misspelt required one).
      const std::vector<std::string> extras = app_.remaining();
      if (!extras.empty() && dynamic_cast<const CLI::ExtrasError*>(&e) == nullptr) {
        std::string list;
        for (const auto& x : extras) list += " " + x;
        return usageError(std::string(extras.size() == 1 ? "The following argument was not expected:"
                                                         : "The following arguments were not expected:") +
                          list);
      }
      return usageError(e.what());
    }
  }

  /// A usage error found after parsing (a check CLI11 cannot express): printed as CLI11's
  /// own are; returns kUsageExitCode. `message` names the flag ("--jpeg: must be in [0, 100]").
  int usageError(const std::string& message) const {
    std::fprintf(stderr, "%s: %s\nRun with --help for more information.\n", name_.c_str(),
                 message.c_str());
    return kUsageExitCode;
  }

 private:
  std::string name_;
  CLI::App app_;
};

/// The failure handler around a program's work (runMain's): returns `body()` (the exit
/// code); an exception escaping it is printed as "PREFIX: MESSAGE" on stderr and gives
/// kFailureExitCode. `prefix`: the program's name, with what failed where that helps
/// ("omniposed: start-up failed").
template <class Body>
int runProgram(const std::string& prefix, Body&& body) {
  try {
    return body();
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s: %s\n", prefix.c_str(), e.what());
    return kFailureExitCode;
  }
}

/// A usage error found while the program works (a value CLI11 cannot check); runMain prints
/// it as Cli::usageError does and returns kUsageExitCode. what(): "--flag: what is wrong".
struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// What a program is called and says about itself in --help.
struct ProgramInfo {
  const char* name;         ///< as installed ("omnipose-eval")
  const char* usage;        ///< the synopsis, "usage: NAME ...", one or more lines
  const char* description;  ///< what it does and its exit codes
  /// Prefix of a failure's message; nullptr: the name ("omniposed: start-up failed").
  const char* failure_prefix = nullptr;
};

/// The whole main() of a program whose command line fills an `Args`:
/// `add_options(app, args)` declares the options on a default-constructed Args, the command
/// line is parsed (--help, --version and usage errors return their exit codes, see
/// Cli::parse), and `body(cli, args)` returns the exit code under runProgram (an exception is
/// "PREFIX: MESSAGE", kFailureExitCode). A check CLI11 cannot express returns
/// `cli.usageError("...")` from the body or throws UsageError. Example: the top of this file.
template <class Args, class AddOptions, class Body>
int runMain(int argc, const char* const* argv, const ProgramInfo& info, AddOptions&& add_options,
            Body&& body) {
  Args args{};
  Cli cli(info.name, info.usage, info.description);
  add_options(cli.app(), args);
  if (const auto exit_code = cli.parse(argc, argv)) return *exit_code;
  return runProgram(info.failure_prefix ? info.failure_prefix : info.name, [&] {
    try {
      return body(cli, args);
    } catch (const UsageError& e) {
      return cli.usageError(e.what());
    }
  });
}

/// Validator: a value CLI11 parsed must be one of `names` (error: "--input: must be omni or
/// panorama, not 'x'"); for options whose conversion the program does itself.
inline CLI::Validator oneOf(std::vector<std::string> names) {
  std::string list;
  for (std::size_t i = 0; i < names.size(); ++i)
    list += (i == 0 ? "" : i + 1 == names.size() ? " or " : ", ") + names[i];
  return CLI::Validator(
      [names, list](std::string& value) -> std::string {
        for (const auto& n : names)
          if (value == n) return {};
        return "must be " + list + ", not '" + value + "'";
      },
      "", "");
}

/// Validator: a number >= 0 ("--count: must be a number >= 0, not '-1'").
inline CLI::Validator nonNegative() {
  return CLI::Validator(
      [](std::string& value) -> std::string {
        try {
          std::size_t pos = 0;
          const double v = std::stod(value, &pos);
          if (pos == value.size() && v >= 0.0) return {};
        } catch (const std::exception&) {
        }
        return "must be a number >= 0, not '" + value + "'";
      },
      "", "");
}

}  // namespace omnipose::tools
