#include "omnipose/config.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <set>
#include <type_traits>
#include <sstream>

namespace omnipose {
namespace {

template <typename T>
const char* typeName() {
  if constexpr (std::is_same_v<T, bool>) return "true or false";
  else if constexpr (std::is_integral_v<T>) return "an integer";
  else if constexpr (std::is_floating_point_v<T>) return "a number";
  else return "text";
}

template <typename T>
std::string fmt(T value) {
  std::ostringstream o;
  o << value;
  return o.str();
}

/// Reads typed values out of a YAML map, collecting every problem with its key path.
class Reader {
 public:
  Reader(std::string origin, std::vector<std::string>& problems)
      : origin_(std::move(origin)), problems_(problems) {}

  void problem(const std::string& key, const std::string& what) {
    problems_.push_back(origin_ + ": " + key + ": " + what);
  }

  /// Reports keys of `node` (a map at `prefix`) that are not in `known`.
  bool checkMap(const YAML::Node& node, const std::string& prefix,
                const std::set<std::string>& known) {
    if (!node.IsMap()) {
      problem(prefix, "must be a map");
      return false;
    }
    for (const auto& kv : node) {
      if (!kv.first.IsScalar()) {
        problem(prefix.empty() ? "(top level)" : prefix, "keys must be plain names");
        continue;
      }
      const auto key = kv.first.Scalar();
      if (!known.contains(key)) problem(join(prefix, key), "unknown key");
    }
    return true;
  }

  static std::string join(const std::string& prefix, const std::string& key) {
    return prefix.empty() ? key : prefix + "." + key;
  }

  template <typename T>
  void get(const YAML::Node& map, const std::string& prefix, const std::string& key, T& value) {
    const YAML::Node node = map[key];
    if (!node) return;
    try {
      value = node.as<T>();
    } catch (const YAML::Exception&) {
      std::string text = node.IsScalar() ? node.Scalar() : YAML::Dump(node);
      if (text.size() > 60) text = text.substr(0, 60) + "...";
      problem(join(prefix, key), "cannot read '" + text + "' as " + typeName<T>());
    }
  }

  /// A number in [lo, hi] (finite; NaN and infinities are refused).
  template <typename T>
  void range(T value, const std::string& key, T lo, T hi, const char* unit = "") {
    if constexpr (std::is_floating_point_v<T>) {
      if (!std::isfinite(value)) {
        problem(key, "must be a finite number, not " + fmt(value));
        return;
      }
    }
    if (value < lo || value > hi)
      problem(key, fmt(value) + " is outside [" + fmt(lo) + ", " + fmt(hi) + "]" + unit);
  }
  /// A number in (lo, hi] (finite).
  template <typename T>
  void rangeAbove(T value, const std::string& key, T lo, T hi, const char* unit = "") {
    if constexpr (std::is_floating_point_v<T>) {
      if (!std::isfinite(value)) {
        problem(key, "must be a finite number, not " + fmt(value));
        return;
      }
    }
    if (value <= lo || value > hi)
      problem(key, fmt(value) + " is outside (" + fmt(lo) + ", " + fmt(hi) + "]" + unit);
  }

  /// Range check helper: reports `what` when `ok` is false.
  void require(bool ok, const std::string& key, const std::string& what) {
    if (!ok) problem(key, what);
  }

 private:
  std::string origin_;
  std::vector<std::string>& problems_;
};

void parseSource(Reader& r, const YAML::Node& node, const std::filesystem::path& base,
                 SourceConfig& s) {
  if (!r.checkMap(node, "source", {"type", "path", "realtime", "loop", "device", "camera",
                                   "width", "height", "fps", "format"}))
    return;
  std::string type = "file";
  r.get(node, "source", "type", type);
  if (type == "file") s.type = SourceConfig::Type::kFile;
  else if (type == "v4l2") s.type = SourceConfig::Type::kV4l2;
  else if (type == "libcamera") s.type = SourceConfig::Type::kLibcamera;
  else r.problem("source.type", "'" + type + "' is not file, v4l2 or libcamera");
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
  r.range(s.width, "source.width", 1, DaemonConfig::kMaxFrameSide, " pixels");
  r.range(s.height, "source.height", 1, DaemonConfig::kMaxFrameSide, " pixels");
  r.rangeAbove(s.fps, "source.fps", 0.0, 1000.0, " frames per second");
}

void parsePipeline(Reader& r, const YAML::Node& node, const std::filesystem::path& base_dir,
                   PipelineOptions& p) {
  if (!r.checkMap(node, "pipeline",
                  {"window", "step", "huber_delta_px", "median", "refine_iterations",
                   "use_rotation_scale", "estimate_rotation_scale", "min_confidence",
                   "inlier_sigmas", "threads", "fftw_wisdom"}))
    return;
  r.get(node, "pipeline", "window", p.registration.window);
  r.get(node, "pipeline", "step", p.registration.step);
  r.get(node, "pipeline", "huber_delta_px", p.fit.huber_delta_px);
  r.get(node, "pipeline", "median", p.fit.median);
  r.get(node, "pipeline", "refine_iterations", p.refine_iterations);
  r.get(node, "pipeline", "use_rotation_scale", p.fit.use_rotation_scale);
  r.get(node, "pipeline", "estimate_rotation_scale", p.registration.estimate_rotation_scale);
  r.get(node, "pipeline", "min_confidence", p.registration.min_confidence);
  r.get(node, "pipeline", "inlier_sigmas", p.fit.inlier_sigmas);
  r.get(node, "pipeline", "threads", p.threads);
  std::string wisdom;
  r.get(node, "pipeline", "fftw_wisdom", wisdom);
  if (!wisdom.empty())
    p.fftw_wisdom = (std::filesystem::path(wisdom).is_absolute() ? std::filesystem::path(wisdom)
                                                                  : base_dir / wisdom)
                        .string();
  // Bounds before anything is sized by them (the pipeline allocates per window).
  r.range(p.registration.window, "pipeline.window", 16, DaemonConfig::kMaxWindow, " pixels");
  r.range(p.registration.step, "pipeline.step", 1, DaemonConfig::kMaxStep, " pixels");
  r.rangeAbove(p.fit.huber_delta_px, "pipeline.huber_delta_px", 0.0, 100.0, " pixels");
  r.range(p.fit.median, "pipeline.median", 0, 15);
  r.range(p.refine_iterations, "pipeline.refine_iterations", 0, 5);
  r.range(p.registration.min_confidence, "pipeline.min_confidence", 0.0, 1.0);
  r.rangeAbove(p.fit.inlier_sigmas, "pipeline.inlier_sigmas", 0.0, 100.0);
  r.range(p.threads, "pipeline.threads", 0, 256, " (0 = all online cores)");
}

void parseLcm(Reader& r, const YAML::Node& node, LcmConfig& l) {
  if (!r.checkMap(node, "lcm", {"url", "pose_channel", "status_channel", "fit_channel",
                                "status_hz"}))
    return;
  r.get(node, "lcm", "url", l.url);
  r.get(node, "lcm", "pose_channel", l.pose_channel);
  r.get(node, "lcm", "status_channel", l.status_channel);
  r.get(node, "lcm", "fit_channel", l.fit_channel);
  r.get(node, "lcm", "status_hz", l.status_hz);
  r.require(!l.pose_channel.empty(), "lcm.pose_channel", "must not be empty");
  r.require(!l.status_channel.empty(), "lcm.status_channel", "must not be empty");
  r.rangeAbove(l.status_hz, "lcm.status_hz", 0.0, 100.0, " Hz");
}

}  // namespace

const char* toString(SourceConfig::Type type) {
  switch (type) {
    case SourceConfig::Type::kFile: return "file";
    case SourceConfig::Type::kV4l2: return "v4l2";
    case SourceConfig::Type::kLibcamera: return "libcamera";
  }
  return "unknown";
}

DaemonConfig DaemonConfig::parse(const std::string& text, const std::string& origin,
                                 const std::filesystem::path& base_dir, Use use) {
  std::vector<std::string> problems;
  Reader r(origin, problems);
  DaemonConfig c;
  c.origin = origin;
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    problems.push_back(origin + ": not valid YAML: " + e.what());
    throw ConfigError(origin + ": invalid configuration:\n  " + problems.front(), problems);
  }
  if (!root || root.IsNull()) root = YAML::Node(YAML::NodeType::Map);
  if (r.checkMap(root, "", {"source", "calibration", "input", "pipeline", "lcm"})) {
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
    else r.problem("input", "'" + input + "' is not omni or panorama");

    if (root["pipeline"]) parsePipeline(r, root["pipeline"], base_dir, c.pipeline);
    if (root["lcm"]) parseLcm(r, root["lcm"], c.lcm);
    for (const auto& p : c.pipeline.validate()) problems.push_back(origin + ": pipeline." + p);
  }
  if (!problems.empty()) {
    std::string what = origin + ": invalid configuration:";
    for (const auto& p : problems) what += "\n  " + p;
    throw ConfigError(what, problems);
  }
  return c;
}

std::vector<std::string> DaemonConfig::checkAgainst(const Calibration& cal,
                                                    const std::string& origin) const {
  std::vector<std::string> problems;
  const auto& r = pipeline.registration;
  const int width = cal.panorama.width, height = cal.panorama.height;
  if (r.window > height || r.window > width) {
    problems.push_back(origin + ": pipeline.window: " + std::to_string(r.window) +
                       " is larger than the panorama (" + std::to_string(width) + " x " +
                       std::to_string(height) + ", " + calibration.string() + ")");
  }
  if (r.step >= 1 && width > 0) {
    const long long windows = (static_cast<long long>(width) + r.step - 1) / r.step;
    const long long samples = windows * r.window * r.window;
    if (samples > kMaxWindowSamples) {
      problems.push_back(origin + ": pipeline.step: " + std::to_string(r.step) + " gives " +
                         std::to_string(windows) + " windows of " + std::to_string(r.window) +
                         " x " + std::to_string(r.window) + " over the " + std::to_string(width) +
                         "-pixel panorama: " + std::to_string(samples) +
                         " window samples, the largest supported is " +
                         std::to_string(kMaxWindowSamples) + " (use a larger step or window)");
    }
  }
  return problems;
}

DaemonConfig DaemonConfig::load(const std::filesystem::path& path, Use use) {
  std::ifstream in(path);
  if (!in) {
    const std::string msg = path.string() + ": cannot open configuration file";
    throw ConfigError(msg, {msg});
  }
  std::stringstream ss;
  ss << in.rdbuf();
  return parse(ss.str(), path.string(), path.parent_path(), use);
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
    << "\n  inlier_sigmas: " << p.fit.inlier_sigmas << "\n  threads: " << p.threads
    << "\n  fftw_wisdom: \"" << p.fftw_wisdom << "\"\n"
    << "lcm:\n  url: \"" << lcm.url << "\"\n  pose_channel: " << lcm.pose_channel
    << "\n  status_channel: " << lcm.status_channel << "\n  fit_channel: \"" << lcm.fit_channel
    << "\"\n  status_hz: " << lcm.status_hz << "\n";
  return o.str();
}

}  // namespace omnipose
