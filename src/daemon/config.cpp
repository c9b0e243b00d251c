#include "daemon/config.hpp"
#include "omnipose/file_io.hpp"

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <numbers>
#include <set>
#include <string_view>
#include <sstream>

#include "common/named_values.hpp"
#include "common/problem_list.hpp"
#include "runtime/worker_pool.hpp"
#include "common/yaml_reader.hpp"
#include "iio/iio_gyro_options.hpp"
#include "omnipose/limits.hpp"

namespace omnipose {
namespace {

using detail::YamlReader;
using Reader = YamlReader;

/// Reads `key`, given in degrees, into `radians` (kept when the key is absent); returns the
/// value in degrees, for messages.
double getDegrees(Reader& r, const YAML::Node& node, const std::string& path,
                  const std::string& key, double& radians) {
  double degrees = radians * 180.0 / std::numbers::pi;
  r.get(node, path, key, degrees);
  radians = degrees * std::numbers::pi / 180.0;
  return degrees;
}

/// A validate() problem of the options' field `field` (radians), named by the daemon.yaml key
/// `key` the user wrote in degrees: "key: <degrees> <range_in_degrees>"; other problems as
/// they are.
std::string inDegrees(std::string problem, std::string_view field, std::string_view key,
                      double degrees, std::string_view range_in_degrees) {
  if (!problem.starts_with(std::string(field) + ":")) return problem;
  return std::string(key) + ": " + std::to_string(degrees) + " " + std::string(range_in_degrees);
}

constexpr detail::Named<SourceConfig::Type> kSourceTypes[] = {
    {SourceConfig::Type::kFile, "file"},
    {SourceConfig::Type::kV4l2, "v4l2"},
    {SourceConfig::Type::kLibcamera, "libcamera"}};

void parseSource(Reader& r, const YAML::Node& node, const std::filesystem::path& base,
                 SourceConfig& s) {
  if (!r.checkMap(node, "source", {"type", "path", "realtime", "loop", "device", "camera",
                                   "width", "height", "fps", "format"}))
    return;
  r.getNamed(node, "source", "type", kSourceTypes, s.type);
  std::string path;
  r.get(node, "source", "path", path);
  if (!path.empty()) {
    s.path = std::filesystem::path(path).is_absolute() ? std::filesystem::path(path) : base / path;
  }
  r.get(node, "source", "realtime", s.realtime);
  r.get(node, "source", "loop", s.loop);
  r.get(node, "source", "device", s.device);
  r.get(node, "source", "camera", s.camera);
  r.get(node, "source", "width", s.width);
  r.get(node, "source", "height", s.height);
  r.get(node, "source", "fps", s.fps);
  r.get(node, "source", "format", s.format);
  if (s.type == SourceConfig::Type::kFile && path.empty())
    r.problem("source.path", "missing (the dataset directory of a file source)");
  if (s.type == SourceConfig::Type::kV4l2 && s.device.empty())
    r.problem("source.device", "must not be empty");
  r.range(s.width, "source.width", 1, limits::kMaxImageSide, " pixels");
  r.range(s.height, "source.height", 1, limits::kMaxImageSide, " pixels");
  r.range(s.fps, "source.fps", 0.0, 1000.0, " frames per second", true);
}

/// daemon.yaml keys that set a PipelineOptions field, with that field's path in
/// PipelineOptions: one table to read the keys by and to name each field's problem by the key
/// the user wrote.
struct PipelineKey {
  const char* yaml;   ///< key path in daemon.yaml
  const char* field;  ///< field path in PipelineOptions (as its validate() names it)
};
constexpr PipelineKey kPipelineKeys[] = {
    {"pipeline.window", "registration.window"},
    {"pipeline.step", "registration.step"},
    {"pipeline.huber_delta_px", "fit.huber_delta_px"},
    {"pipeline.median", "fit.median"},
    {"pipeline.refine_iterations", "refine_iterations"},
    {"pipeline.use_rotation_scale", "fit.use_rotation_scale"},
    {"pipeline.estimate_rotation_scale", "registration.estimate_rotation_scale"},
    {"pipeline.min_confidence", "registration.min_confidence"},
    {"pipeline.inlier_sigmas", "fit.inlier_sigmas"},
    {"pipeline.moving_content", "moving_content"},
    {"pipeline.dewarp_by_fit", "dewarp_by_fit"},
    {"pipeline.yaw_capture_time", "yaw_capture_time"},
    {"pipeline.gyro_fusion", "gyro_fusion"},
    {"pipeline.noise_weighting", "registration.noise_weighting"},
    {"pipeline.cubic_window_sampling", "registration.cubic_sampling"},
    {"pipeline.plane_depth_prior", "fit.plane_depth_prior"},
    {"pipeline.ring_consensus", "fit.ring_consensus"},
    {"pipeline.vertical_scale", "fit.vertical_scale"},
    {"pipeline.translation_shrinkage", "fit.translation_shrinkage"},
    {"pipeline.planar_motion_deg", "fit.planar_motion_deg"},
    {"pipeline.threads", "threads"},
    {"pipeline.fftw_wisdom", "fftw_wisdom"},
    {"input", "unwrap.input"},
};

/// A PipelineOptions problem ("registration.window: ...") keyed by the daemon.yaml key that
/// sets the field ("pipeline.window: ..."); a field no key sets keeps its path, marked as a
/// built-in value.
std::string yamlProblem(const std::string& problem) {
  for (const PipelineKey& k : kPipelineKeys) {
    const std::string field = std::string(k.field) + ":";
    if (problem.rfind(field, 0) == 0) return k.yaml + problem.substr(field.size() - 1);
  }
  return "pipeline (built-in value) " + problem;
}

void parsePipeline(Reader& r, const YAML::Node& node, const std::filesystem::path& base_dir,
                   PipelineOptions& p) {
  std::vector<std::string> known;
  for (const PipelineKey& k : kPipelineKeys) {
    const std::string_view yaml = k.yaml;
    if (yaml.starts_with("pipeline.")) known.emplace_back(yaml.substr(9));
  }
  if (!r.checkMap(node, "pipeline", known)) return;
  r.get(node, "pipeline", "window", p.registration.window);
  r.get(node, "pipeline", "step", p.registration.step);
  r.get(node, "pipeline", "huber_delta_px", p.fit.huber_delta_px);
  r.get(node, "pipeline", "median", p.fit.median);
  r.get(node, "pipeline", "refine_iterations", p.refine_iterations);
  r.get(node, "pipeline", "use_rotation_scale", p.fit.use_rotation_scale);
  r.get(node, "pipeline", "estimate_rotation_scale", p.registration.estimate_rotation_scale);
  r.get(node, "pipeline", "min_confidence", p.registration.min_confidence);
  r.get(node, "pipeline", "inlier_sigmas", p.fit.inlier_sigmas);
  r.get(node, "pipeline", "moving_content", p.moving_content);
  r.get(node, "pipeline", "dewarp_by_fit", p.dewarp_by_fit);
  r.get(node, "pipeline", "yaw_capture_time", p.yaw_capture_time);
  r.get(node, "pipeline", "gyro_fusion", p.gyro_fusion);
  r.get(node, "pipeline", "noise_weighting", p.registration.noise_weighting);
  r.get(node, "pipeline", "cubic_window_sampling", p.registration.cubic_sampling);
  r.get(node, "pipeline", "plane_depth_prior", p.fit.plane_depth_prior);
  r.get(node, "pipeline", "ring_consensus", p.fit.ring_consensus);
  r.get(node, "pipeline", "vertical_scale", p.fit.vertical_scale);
  r.get(node, "pipeline", "translation_shrinkage", p.fit.translation_shrinkage);
  r.get(node, "pipeline", "planar_motion_deg", p.fit.planar_motion_deg);
  r.get(node, "pipeline", "threads", p.threads);
  std::string wisdom;
  r.get(node, "pipeline", "fftw_wisdom", wisdom);
  if (!wisdom.empty())
    p.fftw_wisdom = (std::filesystem::path(wisdom).is_absolute() ? std::filesystem::path(wisdom)
                                                                  : base_dir / wisdom)
                        .string();
  // The ranges are the pipeline's own (PipelineOptions::validate(), checked by parse()
  // before anything is sized by them).
}

void parseKeyframes(Reader& r, const YAML::Node& node, KeyframeOptions& k) {
  if (!r.checkMap(node, "keyframes",
                  {"slots", "max_translation", "max_tilt_deg", "anchor_gain", "anchor_interval",
                   "min_ring_peak", "gap_after_s"}))
    return;
  r.get(node, "keyframes", "slots", k.slots);
  r.get(node, "keyframes", "max_translation", k.max_translation);
  const double tilt_deg = getDegrees(r, node, "keyframes", "max_tilt_deg", k.max_tilt_rad);
  r.get(node, "keyframes", "anchor_gain", k.anchor_gain);
  r.get(node, "keyframes", "anchor_interval", k.anchor_interval);
  r.get(node, "keyframes", "min_ring_peak", k.min_ring_peak);
  r.get(node, "keyframes", "gap_after_s", k.gap_after_s);
  // The ranges are the odometry's own (KeyframeOptions::validate(), checked by parse()),
  // named by the key the user wrote (degrees where the field is in radians).
  for (const std::string& p : k.validate())
    r.add("keyframes." + inDegrees(p, "max_tilt_rad", "max_tilt_deg", tilt_deg,
                                   "deg is outside [0, 28.6]"));
}

void parseLoopClosure(Reader& r, const YAML::Node& node, const std::filesystem::path& base_dir,
                      LoopClosureOptions& l, MapFileConfig& m) {
  if (!r.checkMap(node, "loop_closure",
                  {"enabled", "max_places", "place_spacing", "search_radius", "min_similarity",
                   "max_correction_deg", "check_interval", "confirmations",
                   "max_turn_rate_deg_s", "map_file", "save_interval_s"}))
    return;
  std::string map_file;
  r.get(node, "loop_closure", "map_file", map_file);
  if (!map_file.empty())
    m.path = std::filesystem::path(map_file).is_absolute() ? std::filesystem::path(map_file)
                                                           : base_dir / map_file;
  r.get(node, "loop_closure", "save_interval_s", m.save_interval_s);
  if (!(m.save_interval_s >= 0.0 && m.save_interval_s <= 86400.0))
    r.add("loop_closure.save_interval_s: " + std::to_string(m.save_interval_s) +
          " is outside [0, 86400] (0: only at shutdown)");
  r.get(node, "loop_closure", "enabled", l.enabled);
  r.get(node, "loop_closure", "max_places", l.max_places);
  r.get(node, "loop_closure", "place_spacing", l.place_spacing);
  r.get(node, "loop_closure", "search_radius", l.search_radius);
  r.get(node, "loop_closure", "min_similarity", l.min_similarity);
  const double correction_deg =
      getDegrees(r, node, "loop_closure", "max_correction_deg", l.max_correction_rad);
  r.get(node, "loop_closure", "check_interval", l.check_interval);
  r.get(node, "loop_closure", "confirmations", l.confirmations);
  const double turn_deg =
      getDegrees(r, node, "loop_closure", "max_turn_rate_deg_s", l.max_turn_rate_rad_s);
  // The ranges are the odometry's own (LoopClosureOptions::validate()), named by the key the
  // user wrote (degrees where the field is in radians).
  for (const std::string& p : l.validate())
    r.add("loop_closure." +
          inDegrees(inDegrees(p, "max_correction_rad", "max_correction_deg", correction_deg,
                              "deg is outside (0, 28.6]"),
                    "max_turn_rate_rad_s", "max_turn_rate_deg_s", turn_deg,
                    "deg/s is outside (0, 5730]"));
}

void parsePlausibility(Reader& r, const YAML::Node& node, PlausibilityOptions& p) {
  if (!r.checkMap(node, "plausibility",
                  {"enabled", "max_repeated_rows", "min_confidence_ratio", "max_rotation_deg_s",
                   "max_rejected"}))
    return;
  r.get(node, "plausibility", "enabled", p.enabled);
  r.get(node, "plausibility", "max_repeated_rows", p.max_repeated_rows);
  r.get(node, "plausibility", "min_confidence_ratio", p.min_confidence_ratio);
  const double rate_deg =
      getDegrees(r, node, "plausibility", "max_rotation_deg_s", p.max_rotation_rad_s);
  r.get(node, "plausibility", "max_rejected", p.max_rejected);
  // The ranges are the odometry's own (PlausibilityOptions::validate()), named by the key the
  // user wrote (max_rotation_deg_s for the field max_rotation_rad_s).
  for (const std::string& problem : p.validate())
    r.add("plausibility." + inDegrees(problem, "max_rotation_rad_s", "max_rotation_deg_s",
                                      rate_deg, "deg/s is outside (0, 18000]"));
}

void parseLcm(Reader& r, const YAML::Node& node, LcmConfig& l) {
  if (!r.checkMap(node, "lcm", {"url", "pose_channel", "status_channel", "fit_channel",
                                "status_hz", "panorama_channel", "panorama_hz",
                                "panorama_width"}))
    return;
  r.get(node, "lcm", "url", l.url);
  r.get(node, "lcm", "pose_channel", l.pose_channel);
  r.get(node, "lcm", "status_channel", l.status_channel);
  r.get(node, "lcm", "fit_channel", l.fit_channel);
  r.get(node, "lcm", "status_hz", l.status_hz);
  if (l.pose_channel.empty()) r.problem("lcm.pose_channel", "must not be empty");
  if (l.status_channel.empty()) r.problem("lcm.status_channel", "must not be empty");
  r.range(l.status_hz, "lcm.status_hz", 0.0, 100.0, " Hz", true);
  r.get(node, "lcm", "panorama_channel", l.panorama_channel);
  r.get(node, "lcm", "panorama_hz", l.panorama_hz);
  r.get(node, "lcm", "panorama_width", l.panorama_width);
  r.range(l.panorama_hz, "lcm.panorama_hz", 0.0, 30.0, " Hz", true);
  r.range(l.panorama_width, "lcm.panorama_width", 64, 4096, " pixels");
}

constexpr detail::Named<ImuConfig::Source> kImuSources[] = {
    {ImuConfig::Source::kNone, "none"}, {ImuConfig::Source::kLcm, "lcm"},
    {ImuConfig::Source::kIio, "iio"}};

/// imu.device and imu.sampling_hz of an iio gyro (the driver's own checks, named by key).
/// The IIO driver's own checks (IioGyroOptions::validate), named by daemon.yaml's keys.
void checkIio(Reader& r, const ImuConfig& i) {
  IioGyroOptions options;
  options.device = i.device;
  options.sampling_hz = i.sampling_hz;
  for (const std::string& problem : options.validate()) {
    const std::size_t colon = problem.find(": ");
    r.problem("imu." + problem.substr(0, colon), problem.substr(colon + 2));
  }
}

void parseImu(Reader& r, const YAML::Node& node, const LcmConfig& lcm, ImuConfig& i) {
  if (!r.checkMap(node, "imu", {"source", "channel", "url", "device", "sampling_hz"})) return;
  r.getNamed(node, "imu", "source", kImuSources, i.source);
  r.get(node, "imu", "channel", i.channel);
  r.get(node, "imu", "url", i.url);
  r.get(node, "imu", "device", i.device);
  r.get(node, "imu", "sampling_hz", i.sampling_hz);
  if (i.source == ImuConfig::Source::kIio) checkIio(r, i);
  if (i.source != ImuConfig::Source::kLcm) return;
  if (i.channel.empty()) r.problem("imu.channel", "must not be empty");
  if (i.url.empty() && lcm.url.find("mode=w") != std::string::npos)
    r.problem("imu.url", "needed: lcm.url \"" + lcm.url + "\" is a log the daemon writes");
}

void parseScheduling(Reader& r, const YAML::Node& node, SchedulingConfig& s) {
  if (!r.checkMap(node, "scheduling", {"fifo_priority", "cpus"})) return;
  r.get(node, "scheduling", "fifo_priority", s.fifo_priority);
  r.get(node, "scheduling", "cpus", s.cpus);
  r.range(s.fifo_priority, "scheduling.fifo_priority", 0, 99);
  if (s.cpus.size() > 1024) r.problem("scheduling.cpus", "more than 1024 CPUs listed");
  for (int cpu : s.cpus) {
    if (cpu < 0) r.problem("scheduling.cpus", std::to_string(cpu) + " is not a CPU number");
  }
}

}  // namespace

const char* toString(SourceConfig::Type type) {
  return detail::nameOf(kSourceTypes, type, "unknown");
}

const char* toString(ImuConfig::Source source) {
  return detail::nameOf(kImuSources, source, "unknown");
}

DaemonConfig DaemonConfig::parse(const std::string& text, const std::string& origin,
                                 const std::filesystem::path& base_dir, Use use) {
  Reader r(origin);
  DaemonConfig c;
  c.origin = origin;
  YAML::Node root = detail::loadYaml(text, origin);
  r.checkDuplicateKeys(root);
  if (!root || root.IsNull()) root = YAML::Node(YAML::NodeType::Map);
  if (r.checkMap(root, "", {"source", "calibration", "input", "pipeline", "keyframes",
                            "plausibility", "loop_closure", "lcm", "scheduling", "imu"})) {
    if (root["source"]) parseSource(r, root["source"], base_dir, c.source);
    else if (use == Use::kDaemon) r.problem("source", "missing section");

    std::string calibration;
    r.get(root, "", "calibration", calibration);
    if (!calibration.empty()) {
      c.calibration = std::filesystem::path(calibration).is_absolute()
                          ? std::filesystem::path(calibration)
                          : base_dir / calibration;
    } else if (use == Use::kDaemon) {
      r.problem("calibration", "missing (path of calibration.yaml)");
    }

    std::string input = "omni";
    r.get(root, "", "input", input);
    if (input == "omni") c.pipeline.unwrap.input = InputKind::kOmni;
    else if (input == "panorama") c.pipeline.unwrap.input = InputKind::kPanorama;
    else r.problem("input", "'" + detail::shown(input) + "' is not omni or panorama");

    if (root["pipeline"]) parsePipeline(r, root["pipeline"], base_dir, c.pipeline);
    if (root["keyframes"]) parseKeyframes(r, root["keyframes"], c.keyframes);
    if (root["plausibility"]) parsePlausibility(r, root["plausibility"], c.plausibility);
    if (root["loop_closure"])
      parseLoopClosure(r, root["loop_closure"], base_dir, c.loop_closure, c.map_file);
    if (!c.map_file.path.empty() && !c.loop_closure.enabled)
      r.add("loop_closure.map_file: set while loop_closure.enabled is false (no map to keep)");
    if (root["lcm"]) parseLcm(r, root["lcm"], c.lcm);
    if (root["scheduling"]) parseScheduling(r, root["scheduling"], c.scheduling);
    if (root["imu"]) parseImu(r, root["imu"], c.lcm, c.imu);
    for (const auto& p : c.pipeline.validate()) r.add(yamlProblem(p));
  }
  r.throwIfProblems("invalid configuration");
  // More workers than cores only makes them wait for each other (the cores this process may
  // run on: its CPU affinity).
  int cores = runtime::WorkerPool::onlineCores();
  if (!c.scheduling.cpus.empty())
    cores = std::min(cores, static_cast<int>(c.scheduling.cpus.size()));
  if (c.pipeline.threads > cores) {
    c.warnings.push_back(origin + ": pipeline.threads: " + std::to_string(c.pipeline.threads) +
                         " is more than the " + std::to_string(cores) +
                         " cores this process may use: " + std::to_string(cores) + " are used");
    c.pipeline.threads = cores;
  }
  return c;
}

std::vector<std::string> DaemonConfig::checkAgainst(const Calibration& cal,
                                                    const std::string& origin) const {
  std::vector<std::string> problems;
  const cv::Size panorama = cal.panorama.size();
  for (const auto& p : WindowRegistration::validate(panorama, pipeline.registration)) {
    std::string text = yamlProblem("registration." + p);
    if (text.find("than the panorama") != std::string::npos)
      text += " (" + calibration.string() + ")";  // name the file the panorama comes from
    problems.push_back(origin + ": " + text);
  }
  if (imu.source != ImuConfig::Source::kNone && !cal.imu)
    problems.push_back(origin + ": imu.source: " + toString(imu.source) +
                       " needs the calibration's imu section (" + calibration.string() +
                       "; measure it with omnipose-calibrate --imu-from)");
  return problems;
}

DaemonConfig DaemonConfig::load(const std::filesystem::path& path, Use use) {
  Expected<std::string> text = readTextFile(path);
  if (!text) throw ConfigError(std::string(text.error().message()) + " (the configuration file)");
  return parse(*text, path.string(), path.parent_path(), use);
}

std::string DaemonConfig::describe() const {
  std::ostringstream o;
  o << "source:\n  type: " << toString(source.type) << "\n";
  if (source.type == SourceConfig::Type::kFile) {
    o << "  path: " << source.path.string() << "\n  realtime: " << std::boolalpha
      << source.realtime << "\n  loop: " << source.loop << "\n";
  } else {
    if (source.type == SourceConfig::Type::kV4l2) o << "  device: " << source.device << "\n";
    else o << "  camera: " << source.camera << "\n";
    o << "  width: " << source.width << "\n  height: " << source.height
      << "\n  fps: " << source.fps << "\n  format: " << source.format << "\n";
  }
  const auto& p = pipeline;
  o << "calibration: " << calibration.string() << "\n"
    << "input: " << (p.unwrap.input == InputKind::kOmni ? "omni" : "panorama") << "\n"
    << "pipeline:\n  window: " << p.registration.window << "\n  step: " << p.registration.step
    << "\n  huber_delta_px: " << p.fit.huber_delta_px << "\n  median: " << p.fit.median
    << "\n  refine_iterations: " << p.refine_iterations << "\n  use_rotation_scale: "
    << std::boolalpha << p.fit.use_rotation_scale
    << "\n  estimate_rotation_scale: " << p.registration.estimate_rotation_scale
    << "\n  min_confidence: " << p.registration.min_confidence
    << "\n  inlier_sigmas: " << p.fit.inlier_sigmas
    << "\n  moving_content: " << p.moving_content
    << "\n  dewarp_by_fit: " << p.dewarp_by_fit
    << "\n  yaw_capture_time: " << p.yaw_capture_time
    << "\n  gyro_fusion: " << p.gyro_fusion
    << "\n  noise_weighting: " << p.registration.noise_weighting
    << "\n  cubic_window_sampling: " << p.registration.cubic_sampling
    << "\n  plane_depth_prior: " << p.fit.plane_depth_prior
    << "\n  ring_consensus: " << p.fit.ring_consensus
    << "\n  vertical_scale: " << p.fit.vertical_scale
    << "\n  translation_shrinkage: " << p.fit.translation_shrinkage
    << "\n  planar_motion_deg: " << p.fit.planar_motion_deg << "\n  threads: " << p.threads
    << "\n  fftw_wisdom: \"" << p.fftw_wisdom << "\"\n"
    << "keyframes:\n  slots: " << keyframes.slots
    << "\n  max_translation: " << keyframes.max_translation
    << "\n  max_tilt_deg: " << keyframes.max_tilt_rad * 180.0 / std::numbers::pi
    << "\n  anchor_gain: " << keyframes.anchor_gain
    << "\n  anchor_interval: " << keyframes.anchor_interval
    << "\n  min_ring_peak: " << keyframes.min_ring_peak
    << "\n  gap_after_s: " << keyframes.gap_after_s << "\n"
    << "plausibility:\n  enabled: " << plausibility.enabled
    << "\n  max_repeated_rows: " << plausibility.max_repeated_rows
    << "\n  min_confidence_ratio: " << plausibility.min_confidence_ratio
    << "\n  max_rotation_deg_s: " << plausibility.max_rotation_rad_s * 180.0 / std::numbers::pi
    << "\n  max_rejected: " << plausibility.max_rejected << "\n"
    << "loop_closure:\n  enabled: " << loop_closure.enabled
    << "\n  max_places: " << loop_closure.max_places
    << "\n  place_spacing: " << loop_closure.place_spacing
    << "\n  search_radius: " << loop_closure.search_radius
    << "\n  min_similarity: " << loop_closure.min_similarity
    << "\n  max_correction_deg: " << loop_closure.max_correction_rad * 180.0 / std::numbers::pi
    << "\n  check_interval: " << loop_closure.check_interval
    << "\n  confirmations: " << loop_closure.confirmations
    << "\n  max_turn_rate_deg_s: " << loop_closure.max_turn_rate_rad_s * 180.0 / std::numbers::pi
    << "\n  map_file: \"" << map_file.path.string() << "\""
    << "\n  save_interval_s: " << map_file.save_interval_s
    << "\n"
    << "lcm:\n  url: \"" << lcm.url << "\"\n  pose_channel: " << lcm.pose_channel
    << "\n  status_channel: " << lcm.status_channel << "\n  fit_channel: \"" << lcm.fit_channel
    << "\"\n  status_hz: " << lcm.status_hz << "\n  panorama_channel: \"" << lcm.panorama_channel
    << "\"\n  panorama_hz: " << lcm.panorama_hz << "\n  panorama_width: " << lcm.panorama_width
    << "\n"
    << "scheduling:\n  fifo_priority: " << scheduling.fifo_priority << "\n  cpus: [";
  for (std::size_t i = 0; i < scheduling.cpus.size(); ++i)
    o << (i > 0 ? ", " : "") << scheduling.cpus[i];
  o << "]\nimu:\n  source: " << toString(imu.source) << "\n  channel: " << imu.channel
    << "\n  url: \"" << imu.url << "\"\n  device: \"" << imu.device
    << "\"\n  sampling_hz: " << imu.sampling_hz << "\n";
  return o.str();
}

}  // namespace omnipose
