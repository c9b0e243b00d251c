#pragma once
/// \file startup_check.hpp
/// `omniposed --check`: the whole start-up validation that needs no hardware, every problem
/// collected instead of stopping at the first.

#include <string>
#include <vector>

#include "daemon/config.hpp"

namespace omnipose::daemon {

/// What checkStartup() found.
struct StartupCheck {
  /// Every problem, each naming the file and the key or field ("daemon.yaml: pipeline.window:
  /// 200 is larger than the panorama ...", "cal.yaml: omni.mask: ..."). Empty: start-up would
  /// get as far as opening the source.
  std::vector<std::string> problems;
  /// One line per thing checked and found usable (for the operator's log).
  std::vector<std::string> findings;

  /// The problems as printed: one per line, at most 20 (then "and N more"), control
  /// characters escaped.
  std::string listing() const;
};

/// Checks, for a configuration that DaemonConfig::load() accepted: the calibration file and
/// what it names (lens model files, mask); the pipeline against its panorama (and builds the
/// pipeline when that fits, so FFT plans and tables are proven too); the source's options as
/// its driver will read them (checkSourceOptions(), source_factory.hpp), without opening a
/// device (a file source: that the dataset directory exists); an IIO gyro found by index or
/// name (IioGyro::find(), nothing opened) and a gyro's need of the calibration's imu section; the FFTW wisdom file and an
/// LCM log (`file://PATH?mode=w`) as things the daemon may replace (file_io.hpp). Writes
/// nothing: the pipeline is built without its wisdom file, no log or lock file is created.
/// Never throws for a problem of the configuration; std::bad_alloc and the like propagate.
StartupCheck checkStartup(const DaemonConfig& config);

}  // namespace omnipose::daemon
