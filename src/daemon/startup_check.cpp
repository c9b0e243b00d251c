#include "daemon/startup_check.hpp"

#include <exception>
#include <filesystem>
#include <string>

#include "common/problem_list.hpp"
#include "daemon/source_factory.hpp"
#include "omnipose/calibration.hpp"
#include "omnipose/pipeline.hpp"

namespace omnipose::daemon {
namespace {

/// The source's options, as the driver would read them; nothing is opened.
void checkSource(const DaemonConfig& config, StartupCheck& out) {
  const std::string origin = config.origin.empty() ? "daemon.yaml" : config.origin;
  const SourceConfig& s = config.source;
  if (s.type == SourceConfig::Type::kFile) {
    std::error_code ec;
    if (!std::filesystem::is_directory(s.path, ec)) {
      out.problems.push_back(origin + ": source.path: " + s.path.string() +
                             " is not a directory (the recorded dataset)");
      return;
    }
    out.findings.push_back("source: file " + s.path.string());
    return;
  }
  const auto problems = checkSourceOptions(s);
  for (const auto& p : problems) out.problems.push_back(origin + ": " + p);
  if (problems.empty())
    out.findings.push_back(std::string("source: ") + toString(s.type) + " " +
                           (s.type == SourceConfig::Type::kV4l2 ? s.device : s.camera) + ", " +
                           std::to_string(s.width) + "x" + std::to_string(s.height) + " " +
                           s.format + ": options valid (the device is not opened by --check)");
}

}  // namespace

StartupCheck checkStartup(const DaemonConfig& config) {
  StartupCheck out;
  const std::string origin = config.origin.empty() ? "daemon.yaml" : config.origin;
  checkSource(config, out);

  Calibration calibration;
  try {
    calibration = Calibration::load(config.calibration);
  } catch (const CalibrationError& e) {
    for (const auto& p : e.problems()) out.problems.push_back(p);
    if (e.problems().empty()) out.problems.push_back(e.what());
    return out;
  } catch (const std::runtime_error& e) {  // unreadable file, lens model file missing
    out.problems.push_back(e.what());
    return out;
  }
  const auto fit = config.checkAgainst(calibration, origin);
  out.problems.insert(out.problems.end(), fit.begin(), fit.end());
  if (!out.problems.empty()) return out;

  try {
    const Pipeline pipeline(calibration, config.pipeline);
    out.findings.push_back(
        "calibration " + config.calibration.string() + ": lens model " +
        toString(calibration.omni.model) + (calibration.omni.mask.empty() ? "" : " with a mask") +
        ", panorama " + std::to_string(calibration.panorama.width) + "x" +
        std::to_string(calibration.panorama.height) + ": usable");
  } catch (const std::invalid_argument& e) {
    out.problems.push_back(config.calibration.string() + ": " + e.what());
  }
  return out;
}

std::string StartupCheck::listing() const { return detail::joinProblems(problems); }

}  // namespace omnipose::daemon
