/// omniposed: estimates the camera's motion from an omni-directional camera (or a replayed
/// dataset directory) and publishes pose and status over LCM. Configuration: daemon.yaml
/// (DESIGN.md section 7, example: tools/omniposed/daemon.example.yaml).
///
/// Exit codes: 0 = stopped by SIGINT/SIGTERM (at any time, start-up included) or a finite
/// source finished; 1 = start-up failed (bad configuration, calibration, source or LCM URL;
/// every problem is printed); 2 = bad command line; 3 = ran, but every message failed to
/// publish.

#include <csignal>
#include <cstdio>
#include <exception>
#include <string>

#include "cli.hpp"
#include "daemon/service.hpp"
#include "daemon/startup_check.hpp"
#include "daemon/config.hpp"
#include "quiet_opencv.hpp"

namespace {

constexpr const char* kDescription =
    "Stops cleanly on SIGINT/SIGTERM (exit 0; a second one during the shutdown is ignored);\n"
    "a finite file source ends the daemon after the last frame's pose and a final status\n"
    "(exit 0). SIGHUP does not reload the configuration: it logs the counters and the daemon\n"
    "keeps running. Exit codes: 0 stopped, 1 start-up failed, 2 bad command line, 3 every\n"
    "message failed to publish.";

/// The command line, as parsed.
struct Args {
  std::string config_path;
  bool check_only = false;
};

void addOptions(CLI::App& app, Args& a) {
  app.add_option("--config", a.config_path,
                 "daemon configuration, YAML (DESIGN.md section 7; example: "
                 "tools/omniposed/daemon.example.yaml)")
      ->type_name("FILE")
      ->required();
  app.add_flag("--check", a.check_only,
               "validate the configuration, the calibration and what it names (lens model, "
               "mask) and the pipeline against it, print the effective values and exit; opens "
               "no camera");
}

/// --check: the whole start-up validation that needs no hardware, every problem at once;
/// writes nothing and starts no daemon.
int check(const omnipose::DaemonConfig& config) {
  // A stop signal may simply end it.
  omnipose::daemon::unblockStopSignals();
  const auto check = omnipose::daemon::checkStartup(config);
  for (const auto& f : check.findings) std::fprintf(stderr, "omniposed: %s\n", f.c_str());
  if (check.problems.empty()) return 0;
  std::fprintf(stderr, "omniposed: %s\n", check.listing().c_str());
  std::fprintf(stderr, "omniposed: --check: %zu problem(s)\n", check.problems.size());
  return 1;
}

int run(const Args& a) {
  const auto config = omnipose::DaemonConfig::load(a.config_path);
  std::fprintf(stderr, "omniposed: configuration %s (effective values):\n%s", a.config_path.c_str(),
               config.describe().c_str());
  for (const std::string& w : config.warnings) std::fprintf(stderr, "omniposed: warning: %s\n", w.c_str());
  std::fflush(stderr);
  return a.check_only ? check(config) : omnipose::daemon::runService(config, stderr);
}

}  // namespace

int main(int argc, char** argv) {
  omnipose::tools::quietOpenCvWarnings();
  // Before anything can start a thread: every thread inherits the blocked stop signals and
  // the main thread collects them with sigtimedwait().
  omnipose::daemon::blockStopSignals();
  // A closed stderr pipe (e.g. the log collector restarted) must not kill the daemon.
  std::signal(SIGPIPE, SIG_IGN);
  return omnipose::tools::runMain<Args>(
      argc, argv,
      {"omniposed", "usage: omniposed --config daemon.yaml [--check]", kDescription,
       "omniposed: start-up failed"},
      addOptions, [](auto&, const Args& args) { return run(args); });
}
