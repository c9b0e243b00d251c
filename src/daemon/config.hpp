#pragma once
/// \file config.hpp
/// The daemon configuration (daemon.yaml, DESIGN.md section 7), parsed in this one place
/// for the daemon and for `omnipose-replay --config` (library omnipose_daemon_config; the
/// daemon's, not part of the installed API). Every key is optional except
/// `source` and `calibration` (for the daemon); unknown keys are errors; every problem is
/// collected and reported at once. describe() gives the effective values for the start-up
/// log.
///
/// ```yaml
/// source: {type: file, path: /data/run1, realtime: true, loop: false}
/// calibration: /etc/omnipose/calibration.yaml   # relative: to this file's folder
/// input: omni                                    # omni | panorama
/// pipeline: {window: 110, step: 20, huber_delta_px: 2.0, median: 5,
///            refine_iterations: 1, use_rotation_scale: true}
/// keyframes: {slots: 4, max_translation: 0.02, max_tilt_deg: 5.16, anchor_gain: 0.1,
///             anchor_interval: 1, min_ring_peak: 0.03, gap_after_s: 0.15}
/// loop_closure: {enabled: true, max_places: 128, place_spacing: 0.1, search_radius: 0.3,
///                min_similarity: 0.9, max_correction_deg: 5.73, check_interval: 6,
///                confirmations: 2, max_turn_rate_deg_s: 28.6}
/// lcm: {url: "", pose_channel: OMNI_POSE, status_channel: OMNI_STATUS, fit_channel: "",
///       status_hz: 1.0, panorama_channel: "", panorama_hz: 2.0, panorama_width: 640}
/// scheduling: {fifo_priority: 0, cpus: []}
/// imu: {source: none, channel: OMNI_IMU, url: "", device: "", sampling_hz: 0}
/// ```

#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "omnipose/config_error.hpp"
#include "omnipose/odometry.hpp"
#include "omnipose/pipeline.hpp"

namespace omnipose {

/// Where frames come from.
struct SourceConfig {
  enum class Type { kFile, kV4l2, kLibcamera };
  Type type = Type::kFile;
  std::filesystem::path path;       ///< file: dataset directory
  bool realtime = true;             ///< file: pace by timestamps (false: as fast as possible)
  bool loop = false;                ///< file: start again at the end
  std::string device = "/dev/video0";  ///< v4l2
  std::string camera = "0";         ///< libcamera: index or id
  int width = 1280;                 ///< v4l2 / libcamera, pixels
  int height = 720;
  double fps = 30.0;
  std::string format = "YUYV";      ///< v4l2: GREY | YUYV | MJPG; libcamera: any it offers
};
const char* toString(SourceConfig::Type type);

/// LCM output.
/// The map kept on disk by the daemon (loop_closure.map_file, loop_closure.save_interval_s).
struct MapFileConfig {
  /// Empty: the map lives and dies with the process. Resolved against the config file's
  /// folder; its directory must exist.
  std::filesystem::path path;
  /// The map is saved this often while running, seconds, [0, 86400]; 0: only at shutdown.
  double save_interval_s = 60.0;
};

struct LcmConfig {
  std::string url;                  ///< "" = LCM's default (udpm multicast)
  std::string pose_channel = "OMNI_POSE";
  std::string status_channel = "OMNI_STATUS";
  std::string fit_channel;          ///< "" = diagnostics off
  double status_hz = 1.0;
  /// Panorama pictures for a viewer (omnipose.panorama_image_t): "" = off.
  std::string panorama_channel;
  double panorama_hz = 2.0;         ///< at most this many per second of capture time
  int panorama_width = 640;         ///< the picture's width at most, pixels
};

/// The robot's gyro (DESIGN.md sections 3 and 6). Its samples are used when the calibration
/// has an imu section and a rolling shutter.
struct ImuConfig {
  /// none; lcm: omnipose.imu_t messages; iio: a Linux IIO gyro read through its buffered
  /// interface (drivers/iio/iio_gyro.hpp).
  enum class Source { kNone, kLcm, kIio };
  Source source = Source::kNone;
  std::string channel = "OMNI_IMU";  ///< lcm: the channel of the omnipose.imu_t messages
  /// lcm: the LCM URL to receive on; "" = lcm.url's (which must then not be a log the daemon
  /// writes: file://...?mode=w).
  std::string url;
  /// iio: `iio:deviceN`, or the device's `name` attribute (e.g. bmi160, lsm6dsx), which is
  /// looked up again when the device comes back (its index may change). Required for iio.
  std::string device;
  /// iio: the sampling frequency to set, Hz; 0 = leave the device's.
  double sampling_hz = 0.0;
};
const char* toString(ImuConfig::Source source);

/// How the daemon's threads are scheduled (src/daemon/scheduling.hpp applies it at start-up,
/// before any thread starts). The default changes nothing: normal time-sharing on every CPU.
struct SchedulingConfig {
  /// 0: the normal policy (SCHED_OTHER). 1-99: every thread of the daemon runs SCHED_FIFO at
  /// this priority: it preempts every normal process on its core (the kernel still leaves them
  /// 5 % of each second, /proc/sys/kernel/sched_rt_runtime_us). Needs CAP_SYS_NICE or an
  /// RLIMIT_RTPRIO of at least the priority; refused at start-up otherwise.
  int fifo_priority = 0;
  /// The CPUs the daemon may run on (sched_setaffinity; numbered as in /proc/cpuinfo); empty:
  /// every CPU. pipeline.threads 0 then means one worker per CPU listed.
  std::vector<int> cpus;
};

struct DaemonConfig {
  /// kDaemon: `source` and `calibration` are required. kReplay: both are optional (the
  /// dataset comes from the command line).
  enum class Use { kDaemon, kReplay };

  /// Upper bounds of the sizes in daemon.yaml are checked before anything is allocated:
  /// source.width and source.height in [1, limits::kMaxImageSide] (the drivers' bound too),
  /// the pipeline section's those of the pipeline (WindowRegistration::kMaxWindow,
  /// kMaxStep, kMaxWindowSamples).

  std::string origin;                 ///< where it was read from (named in messages)
  SourceConfig source;
  std::filesystem::path calibration;  ///< resolved against the config file's folder
  /// Includes the input kind (pipeline.unwrap.input). threads defaults to 0 here: the daemon
  /// and the replay (with or without a daemon.yaml) use every online core.
  PipelineOptions pipeline = allCores();
  KeyframeOptions keyframes;          ///< keyframes section (max_tilt_deg in degrees there)
  /// plausibility section (max_rotation_deg_s in degrees per second there).
  PlausibilityOptions plausibility;
  /// loop_closure section (max_correction_deg and max_turn_rate_deg_s in degrees there).
  LoopClosureOptions loop_closure;
  /// loop_closure.map_file and loop_closure.save_interval_s: where the daemon keeps the map
  /// across restarts (map_keeper.hpp).
  MapFileConfig map_file;
  LcmConfig lcm;
  SchedulingConfig scheduling;
  ImuConfig imu;
  /// What parse() changed or assumed that the user should know, each naming the file and
  /// the key: pipeline.threads above the cores this process may use is clamped to them.
  std::vector<std::string> warnings;

  /// The pipeline defaults of the daemon and the replay: the library's, on every online core.
  static PipelineOptions allCores() {
    PipelineOptions p;
    p.threads = 0;
    return p;
  }

  /// The pipeline and keyframe settings as the Odometry takes them.
  OdometryOptions odometry() const { return {pipeline, keyframes, plausibility, loop_closure}; }

  /// Reads and validates `path`. Throws ConfigError listing every problem, each prefixed
  /// with the path and the key (e.g. "daemon.yaml: pipeline.step: must be > 0").
  static DaemonConfig load(const std::filesystem::path& path, Use use = Use::kDaemon);
  /// Parses YAML text; relative paths are resolved against `base_dir`.
  static DaemonConfig parse(const std::string& yaml_text, const std::string& origin,
                            const std::filesystem::path& base_dir, Use use = Use::kDaemon);
  /// Problems of the pipeline section together with the calibration's panorama (window
  /// taller than the panorama, more window samples than WindowRegistration::
  /// kMaxWindowSamples), and a gyro (imu.source lcm or iio) without the calibration's imu
  /// section, each naming `origin` (this file) and the daemon.yaml key; empty when it fits.
  /// Checked before anything is sized.
  std::vector<std::string> checkAgainst(const Calibration& cal, const std::string& origin) const;
  /// The effective configuration as YAML, for the start-up log.
  std::string describe() const;
};

}  // namespace omnipose
