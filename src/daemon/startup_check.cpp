#include "daemon/startup_check.hpp"

#include "daemon/scheduling.hpp"

#include <exception>
#include <filesystem>
#include <optional>
#include <string>

#include "common/problem_list.hpp"
#include "daemon/message_sink.hpp"
#include "daemon/source_factory.hpp"
#include "iio/iio_gyro.hpp"
#include "map/map_file.hpp"
#include "omnipose/io/dataset.hpp"
#include "omnipose/calibration.hpp"
#include "omnipose/pipeline.hpp"
#include "runtime/fft_plan.hpp"

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

/// A file source's recording as the source will read it (timestamps.txt, groundtruth.tum,
/// the frame list), with the daemon's calibration, which has been checked already.
void checkRecording(const DaemonConfig& config, StartupCheck& out) {
  if (config.source.type != SourceConfig::Type::kFile) return;
  const std::string origin = config.origin.empty() ? "daemon.yaml" : config.origin;
  try {
    const Dataset dataset = Dataset::open(config.source.path, config.calibration);
    out.findings.push_back("recording " + config.source.path.string() + ": " +
                           std::to_string(dataset.frames.size()) + " frames");
    for (const std::string& w : dataset.warnings) out.findings.push_back("warning: " + w);
  } catch (const std::exception& e) {
    out.problems.push_back(origin + ": source.path: " + e.what());
  }
}

/// pipeline.fftw_wisdom: a wisdom file, or nothing yet where the directory exists.
void checkWisdom(const DaemonConfig& config, StartupCheck& out) {
  const std::string& path = config.pipeline.fftw_wisdom;
  if (path.empty()) return;
  const std::string origin = config.origin.empty() ? "daemon.yaml" : config.origin;
  if (const std::optional<std::string> problem = runtime::wisdomFileProblem(path)) {
    out.problems.push_back(origin + ": pipeline.fftw_wisdom: " + *problem);
    return;
  }
  std::error_code ec;
  const std::filesystem::path file(path);
  if (std::filesystem::exists(file, ec)) {
    out.findings.push_back("fftw_wisdom " + path + ": a wisdom file of " +
                           std::to_string(std::filesystem::file_size(file, ec)) + " bytes");
  } else if (std::filesystem::is_directory(file.has_parent_path() ? file.parent_path() : ".", ec)) {
    out.findings.push_back("fftw_wisdom " + path + ": absent; written after the first start-up plans");
  } else {
    out.findings.push_back("fftw_wisdom " + path + ": its directory does not exist; the plans are "
                           "not kept (every start-up plans again)");
  }
}

/// loop_closure.map_file: a map to load (what it holds), or none yet where its directory
/// exists; a file that cannot be used is a finding (the daemon starts with an empty map), a
/// directory that does not exist a problem (the map could never be saved).
void checkMapFile(const DaemonConfig& config, const Calibration& calibration, StartupCheck& out) {
  const std::filesystem::path& file = config.map_file.path;
  if (file.empty()) return;
  const std::string origin = config.origin.empty() ? "daemon.yaml" : config.origin;
  map::MapSnapshot snapshot;
  const Expected<void> loaded =
      map::loadMap(file, calibration, config.loop_closure.max_places, snapshot);
  std::error_code ec;
  if (loaded) {
    out.findings.push_back("map_file " + file.string() + ": " +
                           std::to_string(snapshot.place_count) + " places, " +
                           std::to_string(snapshot.edges.size()) + " edges (loaded at start-up)");
  } else if (loaded.error().code() != ErrorCode::kNotFound) {
    out.findings.push_back(std::string("map_file: ") + loaded.error().c_str() +
                           "; the daemon would start with an empty map");
  } else if (std::filesystem::is_directory(file.has_parent_path() ? file.parent_path() : ".", ec)) {
    out.findings.push_back("map_file " + file.string() + ": none yet; written while running");
  } else {
    out.problems.push_back(origin + ": loop_closure.map_file: " + file.string() +
                           ": its directory does not exist (the map could never be saved)");
  }
}

/// imu.source iio: the device found under /sys/bus/iio/devices (by index or name), nothing
/// opened or written; the calibration's imu section is checkAgainst()'s.
void checkImu(const DaemonConfig& config, StartupCheck& out) {
  if (config.imu.source != ImuConfig::Source::kIio) return;
  const std::string origin = config.origin.empty() ? "daemon.yaml" : config.origin;
  IioGyroOptions options;
  options.device = config.imu.device;
  IioGyro gyro(options);
  if (const Expected<std::string> found = gyro.find(); found)
    out.findings.push_back("imu: iio gyro " + *found + ": found (opened at start-up)");
  else
    out.problems.push_back(origin + ": imu.device: " + found.error().c_str());
}

}  // namespace

StartupCheck checkStartup(const DaemonConfig& config) {
  StartupCheck out;
  const std::string origin = config.origin.empty() ? "daemon.yaml" : config.origin;
  checkSource(config, out);
  checkImu(config, out);
  if (const std::optional<std::string> problem = logProblem(config.lcm.url))
    out.problems.push_back(origin + ": " + *problem);
  for (const std::string& problem : checkScheduling(config.scheduling))
    out.problems.push_back(origin + ": " + problem);

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
  if (std::filesystem::is_directory(config.source.path)) checkRecording(config, out);
  const auto fit = config.checkAgainst(calibration, origin);
  out.problems.insert(out.problems.end(), fit.begin(), fit.end());
  if (!out.problems.empty()) return out;

  checkWisdom(config, out);
  checkMapFile(config, calibration, out);
  try {
    // Without the wisdom file: --check writes nothing (planning would save it).
    PipelineOptions options = config.pipeline;
    options.fftw_wisdom.clear();
    const Pipeline pipeline(calibration, options);
    out.findings.push_back(
        "calibration " + config.calibration.string() + ": lens model " +
        toString(calibration.omni.model) + (calibration.omni.mask.empty() ? "" : " with a mask") +
        ", panorama " + std::to_string(calibration.panorama.width) + "x" +
        std::to_string(calibration.panorama.height) + ": usable");
  } catch (const std::invalid_argument& e) {
    out.problems.push_back(config.calibration.string() + ": " + e.what());
  }
  out.findings.push_back("scheduling: " + describeScheduling(config.scheduling));
  return out;
}

std::string StartupCheck::listing() const { return detail::joinProblems(problems); }

}  // namespace omnipose::daemon
