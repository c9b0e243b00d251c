#include "replay.hpp"

#include <algorithm>
#include <cmath>
#include <span>
#include <chrono>
#include <fstream>
#include <stdexcept>

#include "omnipose/baselines/feature_motion_estimator.hpp"
#include "omnipose/io/replay.hpp"
#include "omnipose/io/trajectory.hpp"
#include "omnipose/odometry.hpp"
#include "map/map_file.hpp"
#include "omnipose/pipeline.hpp"
#include "progress_line.hpp"

namespace omnipose::replay {

std::vector<std::string> methodNames() {
  std::vector<std::string> names{"ifmi"};
  for (const auto& m : baselines::FeatureMotionOptions::methodNames()) names.push_back(m);
  return names;
}

std::unique_ptr<MotionEstimator> makeEstimator(const std::string& method,
                                               const Calibration& calibration,
                                               const PipelineOptions& options) {
  if (method == "ifmi") return std::make_unique<Pipeline>(calibration, options);
  // Feature baselines: same unwrapping (input kind, black-frame threshold).
  if (auto feature = baselines::FeatureMotionOptions::forMethod(method)) {
    feature->unwrap = options.unwrap;
    return std::make_unique<baselines::FeatureMotionEstimator>(calibration, *feature);
  }
  std::string known;
  for (const auto& m : methodNames()) known += (known.empty() ? "" : ", ") + m;
  throw std::invalid_argument("unknown method '" + method + "' (known: " + known + ")");
}

namespace {

void writeCsvHeader(std::ofstream& csv) {
  csv << "frame,timestamp,file,prev_frame,status,rx,ry,rz,tdir_x,tdir_y,tdir_z,tau_norm,"
         "residual_px,windows_used,windows_total,seconds,state,segment,keyframe,unwrap_s,"
         "registration_s,fit_s,refine_s\n";
}

void writeCsvRow(std::ofstream& csv, int frame, const DatasetFrame& f, const OdometryResult& r) {
  const FrameMotion& m = r.relative;
  const MotionEstimate& e = m.estimate;
  char buf[600];
  std::snprintf(buf, sizeof(buf),
                "%d,%.6f,%s,%lld,%s,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.9g,%.4f,%d,%d,%.6f,%s,%d,%lld,"
                "%.6f,%.6f,%.6f,%.6f\n",
                frame, f.timestamp, f.path.filename().c_str(),
                static_cast<long long>(r.reference_sequence), toString(e.status), e.omega.x(),
                e.omega.y(), e.omega.z(), m.translation_direction.x(),
                m.translation_direction.y(), m.translation_direction.z(), m.tau_norm,
                e.residual_rms_px, e.windows_used, e.windows_total, m.timing.total,
                toString(r.state), r.segment, static_cast<long long>(r.keyframe_sequence),
                m.timing.unwrap, m.timing.registration, m.timing.fit, m.timing.refine);
  csv << buf;
}

}  // namespace

std::unique_ptr<Odometry> makeOdometry(const std::string& method, const Calibration& calibration,
                                       const OdometryOptions& options) {
  if (method == "ifmi") return std::make_unique<Odometry>(calibration, options);
  return std::make_unique<Odometry>(makeEstimator(method, calibration, options.pipeline));
}

namespace {

void loadMapInto(const std::filesystem::path& path, const Calibration& calibration,
                 const OdometryOptions& options, Odometry& odometry) {
  map::MapSnapshot snapshot;
  if (const Expected<void> loaded = map::loadMap(path, calibration,
                                                 options.loop_closure.max_places, snapshot);
      !loaded)
    throw std::runtime_error(std::string("--map-in: ") + loaded.error().c_str());
  if (const Expected<void> restored = odometry.restoreMap(snapshot); !restored)
    throw std::runtime_error("--map-in " + path.string() + ": " + restored.error().c_str());
}

}  // namespace

ReplaySummary run(const ReplayOptions& options, std::FILE* log) {
  OdometryOptions odometry_options = DaemonConfig{}.odometry();  // what the daemon runs
  if (options.config) {
    const DaemonConfig config = DaemonConfig::load(*options.config, DaemonConfig::Use::kReplay);
    for (const std::string& w : config.warnings) std::fprintf(log, "warning: %s\n", w.c_str());
    odometry_options = config.odometry();
  }
  if (options.input) odometry_options.pipeline.unwrap.input = *options.input;
  Dataset dataset = Dataset::open(options.dataset, options.calibration);
  if (const std::string assumed = dataset.assumptions(); !assumed.empty())
    std::fprintf(log, "warning: %s\n", assumed.c_str());
  for (const std::string& w : dataset.warnings) std::fprintf(log, "warning: %s\n", w.c_str());
  if (options.from < 0 || options.from >= static_cast<int>(dataset.frames.size()))
    throw std::invalid_argument("--from " + std::to_string(options.from) + ": the dataset has " +
                                std::to_string(dataset.frames.size()) + " frames");
  dataset.frames.erase(dataset.frames.begin(), dataset.frames.begin() + options.from);
  if (options.count < 0) throw std::invalid_argument("--count " + std::to_string(options.count) + ": negative");
  if (options.count > 0 && options.count < static_cast<int>(dataset.frames.size()))
    dataset.frames.resize(static_cast<std::size_t>(options.count));
  auto odometry = makeOdometry(options.method, dataset.calibration, odometry_options);
  if (options.map_in)
    loadMapInto(*options.map_in, dataset.calibration, odometry_options, *odometry);
  std::string gyro_warning;
  std::vector<GyroSample> gyro = datasetGyroSamples(dataset, gyro_warning);
  if (!gyro_warning.empty()) std::fprintf(log, "warning: %s\n", gyro_warning.c_str());
  if (options.method != "ifmi") gyro.clear();

  std::ofstream csv;
  if (options.relative_csv) {
    csv.open(*options.relative_csv);
    if (!csv) throw std::runtime_error(options.relative_csv->string() + ": cannot write");
    writeCsvHeader(csv);
  }

  std::vector<StampedPose> trajectory, odometry_trajectory;
  std::vector<double> seconds;
  int loops_closed = 0, places = 0, relocalised_at = -1;
  seconds.reserve(dataset.frames.size());
  tools::ProgressLine progress(log, static_cast<int>(dataset.frames.size()), "frames",
                               options.progress);
  const ReplayCounts counts = replayDataset(
      dataset, *odometry, gyro, odometry_options.pipeline.unwrap.input, trajectory,
      [&](int i, const DatasetFrame& f, const OdometryResult& result) {
        seconds.push_back(result.relative.timing.total);
        if (result.state != TrackState::kLost)
          odometry_trajectory.push_back({f.timestamp, result.pose});
        loops_closed += result.loop_closed ? 1 : 0;
        if (options.map_in && relocalised_at < 0 && result.loop_closed) relocalised_at = i + options.from;
        places = result.places;
        if (csv.is_open() && result.relative.has_motion) writeCsvRow(csv, i, f, result);
        progress.update(i + 1);
      },
      [&](const std::string& line) { std::fprintf(log, "%s\n", line.c_str()); });
  progress.finish();
  ReplaySummary summary;
  static_cast<ReplayCounts&>(summary) = counts;
  summary.loops_closed = loops_closed;
  summary.places = places;
  summary.relocalised_at = relocalised_at;
  if (options.map_out) {
    map::MapSnapshot snapshot;
    if (!odometry->snapshotMap(snapshot))
      throw std::invalid_argument("--map-out: there is no map (loop_closure off, or --method " +
                                  options.method + ")");
    if (const Expected<void> saved = map::saveMap(*options.map_out, snapshot); !saved)
      throw std::runtime_error(std::string("--map-out: ") + saved.error().c_str());
  }
  if (!gyro.empty()) {
    const GyroCounters g = odometry->gyroCounters();
    summary.gyro_frames = static_cast<int>(g.frames_with_gyro);
    std::fprintf(log,
                 "gyro: %s, %lld samples taken; rows' rotations from the gyro in %lld frames, "
                 "from the images alone in %lld (not covered); %lld gaps bridged by the gyro; "
                 "bias %.5f %.5f %.5f rad/s (sigma %.5f, %lld readings); windows' yaw read "
                 "%+.4f ms after their modelled capture times\n",
                 dataset.gyro_file->c_str(), static_cast<long long>(g.accepted),
                 static_cast<long long>(g.frames_with_gyro),
                 static_cast<long long>(g.frames_without_gyro),
                 static_cast<long long>(g.frames_gyro_bridged), g.bias.x(), g.bias.y(), g.bias.z(),
                 g.bias_sigma, static_cast<long long>(g.bias_readings), 1e3 * g.yaw_time_offset_s);
  }
  if (const LoopClosureCounters m = odometry->loopClosureCounters(); m.compared > 0)
    std::fprintf(log,
                 "map: frames registered against a place %lld times; refused: %lld without a "
                 "clear heading on the ring, %lld turned too far, %lld fits failed, %lld too far; "
                 "%lld verified, %lld look-alike disagreements, %lld loops closed\n",
                 static_cast<long long>(m.compared), static_cast<long long>(m.no_ring_peak),
                 static_cast<long long>(m.turned_too_far), static_cast<long long>(m.fit_failed),
                 static_cast<long long>(m.too_far), static_cast<long long>(m.verified),
                 static_cast<long long>(m.disagreed), static_cast<long long>(m.closures));
  if (options.out_tum) writeTum(*options.out_tum, trajectory);
  if (options.out_odometry_tum) writeTum(*options.out_odometry_tum, odometry_trajectory);
  if (!seconds.empty()) {
    std::nth_element(seconds.begin(), seconds.begin() + seconds.size() / 2, seconds.end());
    summary.median_seconds_per_frame = seconds[seconds.size() / 2];
  }
  return summary;
}

}  // namespace omnipose::replay
