/// omniposed: estimates the camera's motion from an omni-directional camera (or a replayed
/// dataset directory) and publishes pose and status over LCM. Configuration: daemon.yaml
/// (DESIGN.md section 7, example: tools/omniposed/daemon.example.yaml).
///
/// Exit codes: 0 = stopped by SIGINT/SIGTERM or a finite source finished; 1 = start-up
/// failed (bad configuration, calibration, source or LCM URL; every problem is printed);
/// 2 = bad command line.

#include <csignal>
#include <cstdio>
#include <cstring>
#include <exception>
#include <string>

#include "daemon/service.hpp"
#include "daemon/startup_check.hpp"
#include "omnipose/config.hpp"

namespace {

constexpr const char* kUsage =
    "usage: omniposed --config daemon.yaml [--check]\n"
    "\n"
    "  --config FILE   daemon configuration (DESIGN.md section 7)\n"
    "  --check         validate the configuration, the calibration and what it names (lens\n"
    "                  model, mask) and the pipeline against it, print the effective values\n"
    "                  and exit; opens no camera\n"
    "  -h, --help      this text\n"
    "\n"
    "Stops cleanly on SIGINT/SIGTERM (exit 0; a second one during the shutdown is ignored);\n"
    "a finite file source ends the daemon after the last frame's pose and a final status\n"
    "(exit 0). SIGHUP does not reload the configuration: it logs the counters and the daemon\n"
    "keeps running.\n";

}  // namespace

int main(int argc, char** argv) {
  // Before anything can start a thread: every thread inherits the blocked stop signals and
  // the main thread collects them with sigtimedwait().
  omnipose::daemon::blockStopSignals();
  // A closed stderr pipe (e.g. the log collector restarted) must not kill the daemon.
  std::signal(SIGPIPE, SIG_IGN);

  std::string config_path;
  bool check_only = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg == "-h" || arg == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    } else if (arg == "--config" && i + 1 < argc) {
      config_path = argv[++i];
    } else if (arg.rfind("--config=", 0) == 0) {
      config_path = arg.substr(std::strlen("--config="));
    } else if (arg == "--check") {
      check_only = true;
    } else {
      std::fprintf(stderr, "omniposed: unknown argument '%s'\n%s", arg.c_str(), kUsage);
      return 2;
    }
  }
  if (config_path.empty()) {
    std::fprintf(stderr, "omniposed: --config is required\n%s", kUsage);
    return 2;
  }

  try {
    const auto config = omnipose::DaemonConfig::load(config_path);
    std::fprintf(stderr, "omniposed: configuration %s (effective values):\n%s", config_path.c_str(),
                 config.describe().c_str());
    std::fflush(stderr);
    if (check_only) {
      // The whole start-up validation that needs no hardware, every problem at once.
      const auto check = omnipose::daemon::checkStartup(config);
      for (const auto& f : check.findings) std::fprintf(stderr, "omniposed: %s\n", f.c_str());
      for (const auto& p : check.problems) std::fprintf(stderr, "omniposed: %s\n", p.c_str());
      if (!check.problems.empty()) {
        std::fprintf(stderr, "omniposed: --check: %zu problem(s)\n", check.problems.size());
        return 1;
      }
      return 0;
    }
    return omnipose::daemon::runService(config, stderr);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "omniposed: start-up failed: %s\n", e.what());
    return 1;
  }
}
