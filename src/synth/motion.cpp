#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <numbers>
#include <random>
#include <sstream>
#include <utility>

#include "common/problem_list.hpp"
#include "omnipose/file_io.hpp"
#include "common/yaml_reader.hpp"
#include "omnipose/synth/motion.hpp"

namespace omnipose::synth {
namespace {

constexpr double kDegToRad = std::numbers::pi / 180.0;

// ------------------------------------------------------------------ presets (YAML text)

const std::map<std::string, std::string>& presets() {
  static const std::map<std::string, std::string> table = {
      {"roll",
       "# Roll: 1..6 deg per frame about the camera x axis, random sign, within 15 deg.\n"
       "segments:\n"
       "  - frames: 99\n"
       "    rotation: {axis: x, step_deg: [1, 6], sign: random, bound_deg: 15}\n"},
      {"pitch",
       "# Pitch: 1..6 deg per frame about the camera y axis, random sign, within 15 deg.\n"
       "segments:\n"
       "  - frames: 99\n"
       "    rotation: {axis: y, step_deg: [1, 6], sign: random, bound_deg: 15}\n"},
      {"yaw",
       "# Yaw: 1..6 deg per frame about the camera z axis, random sign.\n"
       "segments:\n"
       "  - frames: 99\n"
       "    rotation: {axis: z, step_deg: [1, 6], sign: random}\n"},
      {"mixed",
       "# Roll, pitch and yaw at once: 1..12 deg per frame about a random axis, within 20 deg.\n"
       "segments:\n"
       "  - frames: 99\n"
       "    rotation: {axis: random, step_deg: [1, 12], bound_deg: 20}\n"},
      {"translate",
       "# Box room: 5..15 cm horizontal steps in random directions, at least 1 m from the\n"
       "# walls, with up to 1 deg of rotation per frame (within 5 deg).\n"
       "wall_margin_m: 1.0\n"
       "segments:\n"
       "  - frames: 99\n"
       "    translation: {step_m: [0.05, 0.15], direction: random_horizontal}\n"
       "    rotation: {axis: random, step_deg: [0, 1], bound_deg: 5}\n"},
      {"demo",
       "# A short tour: yaw, roll, pitch, then translation.\n"
       "segments:\n"
       "  - frames: 15\n"
       "    rotation: {axis: z, step_deg: [2, 4], sign: positive}\n"
       "  - frames: 15\n"
       "    rotation: {axis: x, step_deg: [1, 3], sign: alternate}\n"
       "  - frames: 14\n"
       "    rotation: {axis: y, step_deg: [1, 3], sign: alternate}\n"
       "  - frames: 15\n"
       "    translation: {step_m: [0.05, 0.15], direction: random_horizontal}\n"},
  };
  return table;
}

// ------------------------------------------------------------------ YAML reading

using detail::YamlReader;
using Reader = YamlReader;
using Need = YamlReader::Need;

RotationStep readRotation(Reader& r, const YAML::Node& node, const std::string& path) {
  RotationStep s;
  if (!node.IsMap()) {
    r.problem(path, "must be a map");
    return s;
  }
  r.checkMap(node, path, {"axis", "step_deg", "sign", "bound_deg"});
  std::string axis, sign = "random";
  r.get(node, path, "axis", axis, Need::kRequired);
  r.getInterval(node, path, "step_deg", s.min_deg, s.max_deg);
  r.get(node, path, "sign", sign);
  r.get(node, path, "bound_deg", s.bound_deg);
  static const std::map<std::string, RotationStep::Axis> axes = {
      {"x", RotationStep::Axis::kX}, {"y", RotationStep::Axis::kY},
      {"z", RotationStep::Axis::kZ}, {"random", RotationStep::Axis::kRandom}};
  static const std::map<std::string, RotationStep::Sign> signs = {
      {"random", RotationStep::Sign::kRandom}, {"alternate", RotationStep::Sign::kAlternate},
      {"positive", RotationStep::Sign::kPositive}, {"negative", RotationStep::Sign::kNegative}};
  if (const auto it = axes.find(axis); it != axes.end()) s.axis = it->second;
  else if (!axis.empty()) r.problem(path + ".axis", "'" + detail::shown(axis) + "' is not x, y, z or random");
  if (const auto it = signs.find(sign); it != signs.end()) s.sign = it->second;
  else r.problem(path + ".sign", "'" + detail::shown(sign) + "' is not random, alternate, positive or negative");
  return s;
}

TranslationStep readTranslation(Reader& r, const YAML::Node& node, const std::string& path) {
  TranslationStep s;
  if (!node.IsMap()) {
    r.problem(path, "must be a map");
    return s;
  }
  r.checkMap(node, path, {"step_m", "direction"});
  r.getInterval(node, path, "step_m", s.min_m, s.max_m);
  const YAML::Node direction = node["direction"];
  if (!direction) return s;
  if (direction.IsScalar() && direction.as<std::string>() == "random_horizontal") return s;
  const std::string what = "must be random_horizontal or a list [x, y, z]";
  if (!direction.IsSequence() || direction.size() != 3) {
    r.problem(path + ".direction", what);
    return s;
  }
  try {
    s.direction = {direction[0].as<double>(), direction[1].as<double>(),
                   direction[2].as<double>()};
    s.random_horizontal = false;
  } catch (const YAML::Exception&) {
    r.problem(path + ".direction", what);
  }
  return s;
}

Vibration readVibration(Reader& r, const YAML::Node& node, const std::string& path) {
  Vibration v;
  if (!node.IsMap()) {
    r.problem(path, "must be a map");
    return v;
  }
  r.checkMap(node, path, {"amplitude_deg", "min_hz", "max_hz", "components", "seed"});
  r.get(node, path, "amplitude_deg", v.amplitude_deg);
  r.get(node, path, "min_hz", v.min_hz);
  r.get(node, path, "max_hz", v.max_hz);
  r.get(node, path, "components", v.components);
  r.get(node, path, "seed", v.seed);
  return v;
}

Walkers readWalkers(Reader& r, const YAML::Node& node, const std::string& path) {
  Walkers w;
  if (!node.IsMap()) {
    r.problem(path, "must be a map");
    return w;
  }
  r.checkMap(node, path,
             {"count", "width_m", "height_m", "base_z", "speed_m_s", "distance_m", "seed"});
  r.get(node, path, "count", w.count);
  r.get(node, path, "width_m", w.width_m);
  r.get(node, path, "height_m", w.height_m);
  if (double base = 0.0; r.get(node, path, "base_z", base)) w.base_z = base;
  r.get(node, path, "speed_m_s", w.speed_m_s);
  r.getInterval(node, path, "distance_m", w.min_distance_m, w.max_distance_m);
  r.get(node, path, "seed", w.seed);
  return w;
}

MotionSegment readSegment(Reader& r, const YAML::Node& node, const std::string& path) {
  MotionSegment s;
  if (!node.IsMap()) {
    r.problem(path, "must be a map");
    return s;
  }
  r.checkMap(node, path, {"frames", "rotation", "translation"});
  r.get(node, path, "frames", s.frames, Need::kRequired);
  if (node["rotation"]) s.rotation = readRotation(r, node["rotation"], path + ".rotation");
  if (node["translation"]) {
    s.translation = readTranslation(r, node["translation"], path + ".translation");
  }
  return s;
}

// ------------------------------------------------------------------ generation

/// Random state of trajectory generation.
struct Generator {
  std::mt19937_64 rng;
  double uniform(double lo, double hi) { return std::uniform_real_distribution<>(lo, hi)(rng); }
  bool coin() { return std::bernoulli_distribution(0.5)(rng); }
  Eigen::Vector3d randomUnit() {
    std::normal_distribution<> n;
    Eigen::Vector3d d;
    do d = Eigen::Vector3d(n(rng), n(rng), n(rng));
    while (d.norm() < 1e-9);
    return d.normalized();
  }
};

/// Rotation vector of one step; `step_in_segment` drives the alternating sign.
Eigen::Vector3d drawRotation(const RotationStep& s, Generator& g, int step_in_segment,
                             const Eigen::Matrix3d& R_prev) {
  const double angle = g.uniform(s.min_deg, s.max_deg) * kDegToRad;
  Eigen::Vector3d omega;
  if (s.axis == RotationStep::Axis::kRandom) {
    omega = angle * g.randomUnit();
  } else {
    const Eigen::Vector3d axis = Eigen::Matrix3d::Identity().col(static_cast<int>(s.axis));
    double sign = 1.0;
    switch (s.sign) {
      case RotationStep::Sign::kRandom: sign = g.coin() ? 1.0 : -1.0; break;
      case RotationStep::Sign::kAlternate: sign = step_in_segment % 2 == 0 ? 1.0 : -1.0; break;
      case RotationStep::Sign::kPositive: sign = 1.0; break;
      case RotationStep::Sign::kNegative: sign = -1.0; break;
    }
    omega = sign * angle * axis;
  }
  if (s.bound_deg > 0) {
    // Angle from the start orientation after the step, and after the opposite step.
    const double ahead = rotationVector(R_prev * rotationFromVector(omega)).norm();
    const double back = rotationVector(R_prev * rotationFromVector(-omega)).norm();
    if (ahead > s.bound_deg * kDegToRad && back < ahead) omega = -omega;
  }
  return omega;
}

/// Translation of one step in the previous camera frame; keeps the camera inside `region`.
/// `direction_sign` flips when a fixed-direction step bounces off the region's boundary.
Eigen::Vector3d drawTranslation(const TranslationStep& s, Generator& g,
                                const Eigen::Isometry3d& T_prev,
                                const std::optional<Eigen::AlignedBox3d>& region,
                                double& direction_sign) {
  constexpr int kAttempts = 100;
  const double distance = g.uniform(s.min_m, s.max_m);
  const Eigen::Vector3d p = T_prev.translation();
  const Eigen::Matrix3d R = T_prev.linear();
  const auto inside = [&](const Eigen::Vector3d& step_world) {
    return !region || region->contains(p + step_world);
  };
  if (s.random_horizontal) {
    for (int i = 0; i < kAttempts; ++i) {
      const double phi = g.uniform(0.0, 2.0 * std::numbers::pi);
      const Eigen::Vector3d step_world(distance * std::cos(phi), distance * std::sin(phi), 0.0);
      if (inside(step_world)) return R.transpose() * step_world;
    }
  } else {
    const Eigen::Vector3d t = distance * s.direction.normalized();
    if (inside(R * (direction_sign * t))) return direction_sign * t;
    direction_sign = -direction_sign;
    if (inside(R * (direction_sign * t))) return direction_sign * t;
  }
  std::ostringstream where;
  where << p.transpose();
  throw MotionError("cannot keep the camera inside the allowed region (at " + where.str() +
                    " m, step " + std::to_string(distance) + " m): room too small for the margin?");
}

// ------------------------------------------------------------------ vibration

/// Duration of a sequence of `frames` frames, seconds: the vibration's period.
double sequenceDuration(int frames, double frame_rate) { return (frames - 1) / frame_rate; }

/// Whole numbers of cycles over `duration` whose frequency lies in [min_hz, max_hz].
std::pair<long, long> wholeCycleRange(const Vibration& v, double duration) {
  constexpr double kSlack = 1e-9;  // a band edge that is a whole-cycle frequency counts
  const long lo = std::max(1L, static_cast<long>(std::ceil(v.min_hz * duration - kSlack)));
  const long hi = static_cast<long>(std::floor(v.max_hz * duration + kSlack));
  return {lo, hi};
}

/// Every problem of drawing `v` for `frames` frames at `frame_rate` Hz.
std::vector<std::string> vibrationProblems(const Vibration& v, int frames, double frame_rate) {
  std::vector<std::string> p = v.validate();
  if (!p.empty() || !(frame_rate > 0)) return p;
  if (v.max_hz >= frame_rate / 2) {
    p.push_back("vibration.max_hz: must be below half the frame rate (" +
                std::to_string(frame_rate / 2) + " Hz)");
    return p;
  }
  if (frames < 2) {
    p.push_back("vibration: needs a sequence of at least 2 frames");
    return p;
  }
  const double duration = sequenceDuration(frames, frame_rate);
  const auto [lo, hi] = wholeCycleRange(v, duration);
  const long available = std::max(0L, hi - lo + 1);
  if (available < v.components) {
    p.push_back("vibration.components: the band [min_hz, max_hz] holds " +
                std::to_string(available) + " frequencies of whole cycles over the " +
                std::to_string(duration) + " s sequence, fewer than " +
                std::to_string(v.components) + " (widen the band or lengthen the sequence)");
  }
  return p;
}

VibrationAxis drawAxis(const Vibration& v, double duration, int frames, double frame_rate,
                       std::mt19937_64& rng) {
  const auto [lo, hi] = wholeCycleRange(v, duration);
  // Without repetition: a partial Fisher-Yates shuffle of lo .. hi, kept sparse (position ->
  // value where a swap moved it), so a long sequence's wide band costs no memory.
  std::map<long, long> moved;
  const auto at = [&](long i) {
    const auto it = moved.find(i);
    return it == moved.end() ? lo + i : it->second;
  };
  VibrationAxis axis;
  for (long i = 0; i < v.components; ++i) {
    const long j = std::uniform_int_distribution<long>(i, hi - lo)(rng);
    const long drawn = at(j);
    moved[j] = at(i);
    moved[i] = drawn;
    axis.frequency_hz.push_back(static_cast<double>(drawn) / duration);
    axis.phase_rad.push_back(std::uniform_real_distribution<>(0.0, 2.0 * std::numbers::pi)(rng));
    axis.weight.push_back(std::uniform_real_distribution<>(0.5, 1.0)(rng));
  }
  axis.scale_rad = 1.0;
  double peak = 0.0;
  for (int k = 0; k < frames; ++k) peak = std::max(peak, std::abs(axis.angle(k / frame_rate)));
  if (!(peak > 0)) throw std::invalid_argument("vibration: the drawn sinusoids vanish at every frame");
  axis.scale_rad = v.amplitude_deg * kDegToRad / peak;
  return axis;
}

}  // namespace

std::vector<std::string> Vibration::validate() const {
  std::vector<std::string> p;
  if (!(amplitude_deg > 0 && amplitude_deg <= 10)) {
    p.push_back("vibration.amplitude_deg: must be in (0, 10] degrees");
  }
  if (!(min_hz > 0)) p.push_back("vibration.min_hz: must be > 0");
  if (!(max_hz >= min_hz)) p.push_back("vibration.max_hz: must be >= min_hz");
  if (components < 1 || components > 16) p.push_back("vibration.components: must be in [1, 16]");
  return p;
}

double VibrationAxis::angle(double t) const {
  double sum = 0.0;
  for (std::size_t i = 0; i < frequency_hz.size(); ++i) {
    sum += weight[i] * std::sin(2.0 * std::numbers::pi * frequency_hz[i] * t + phase_rad[i]);
  }
  return scale_rad * sum;
}

Eigen::Matrix3d VibrationSignal::rotation(double t) const {
  return rotationFromVector(Eigen::Vector3d(roll.angle(t), pitch.angle(t), 0.0));
}

VibrationSignal drawVibration(const Vibration& vibration, int frames, double frame_rate) {
  if (!(frame_rate > 0)) throw std::invalid_argument("drawVibration: frame_rate must be > 0");
  detail::throwIfProblems("drawVibration: invalid vibration",
                          vibrationProblems(vibration, frames, frame_rate));
  std::mt19937_64 rng(vibration.seed);
  const double duration = sequenceDuration(frames, frame_rate);
  VibrationSignal signal;
  signal.roll = drawAxis(vibration, duration, frames, frame_rate, rng);
  signal.pitch = drawAxis(vibration, duration, frames, frame_rate, rng);
  return signal;
}

std::vector<std::string> MotionScript::validate() const {
  std::vector<std::string> p;
  if (!(frame_rate > 0)) p.push_back("frame_rate: must be > 0");
  if (frames < 0) p.push_back("frames: must be >= 0 (0 = from the segments)");
  if (!(wall_margin_m >= 0)) p.push_back("wall_margin_m: must be >= 0");
  if (segments.empty()) p.push_back("segments: at least one segment is needed");
  for (std::size_t i = 0; i < segments.size(); ++i) {
    const std::string at = "segments[" + std::to_string(i) + "]";
    const MotionSegment& s = segments[i];
    if (s.frames < 1) p.push_back(at + ".frames: must be >= 1");
    if (const auto& r = s.rotation) {
      if (!(r->min_deg >= 0 && r->min_deg <= r->max_deg && r->max_deg <= 180)) {
        p.push_back(at + ".rotation.step_deg: need 0 <= min <= max <= 180");
      }
      if (!(r->bound_deg >= 0)) p.push_back(at + ".rotation.bound_deg: must be >= 0");
    }
    if (const auto& t = s.translation) {
      if (!(t->min_m >= 0 && t->min_m <= t->max_m)) {
        p.push_back(at + ".translation.step_m: need 0 <= min <= max");
      }
      if (!t->random_horizontal && !(t->direction.norm() > 0)) {
        p.push_back(at + ".translation.direction: must not be zero");
      }
    }
  }
  if (walkers) {
    for (auto& problem : walkers->validate()) p.push_back(std::move(problem));
  }
  if (vibration && frames >= 0 && !segments.empty()) {
    for (auto& problem : vibrationProblems(*vibration, frameCount(), frame_rate)) {
      p.push_back(std::move(problem));
    }
  }
  return p;
}

std::optional<VibrationSignal> MotionScript::vibrationSignal() const {
  if (!vibration) return std::nullopt;
  return drawVibration(*vibration, frameCount(), frame_rate);
}

int MotionScript::frameCount() const {
  if (frames > 0) return frames;
  int n = 1;
  for (const auto& s : segments) n += s.frames;
  return n;
}

bool MotionScript::translates() const {
  for (const auto& s : segments) {
    if (s.translation && s.translation->max_m > 0) return true;
  }
  return false;
}

MotionScript MotionScript::parse(const std::string& yaml_text, const std::string& origin,
                                 std::optional<int> frames) {
  const YAML::Node root = detail::loadYaml(yaml_text, origin);
  Reader r(origin);
  r.checkDuplicateKeys(root);
  MotionScript script;
  if (!root || !root.IsMap()) {
    r.problem("(document)", "expected a map with a 'segments' list");
  } else {
    r.checkMap(root, "", {"seed", "frame_rate", "frames", "wall_margin_m", "segments",
                          "vibration", "walkers"});
    r.get(root, "", "seed", script.seed);
    r.get(root, "", "frame_rate", script.frame_rate);
    r.get(root, "", "frames", script.frames);
    r.get(root, "", "wall_margin_m", script.wall_margin_m);
    if (const YAML::Node vibration = Reader::child(root, "vibration")) {
      script.vibration = readVibration(r, vibration, "vibration");
    }
    if (const YAML::Node walkers = Reader::child(root, "walkers")) {
      script.walkers = readWalkers(r, walkers, "walkers");
    }
    const YAML::Node segments = root["segments"];
    if (!segments) {
      r.problem("segments", "missing");
    } else if (!segments.IsSequence()) {
      r.problem("segments", "must be a list");
    } else {
      for (std::size_t i = 0; i < segments.size(); ++i) {
        script.segments.push_back(
            readSegment(r, segments[i], "segments[" + std::to_string(i) + "]"));
      }
    }
  }
  if (frames) script.frames = *frames;
  if (r.problems().empty()) {
    for (const auto& p : script.validate()) r.add(p);
  }
  r.throwIfProblems(frames ? "invalid motion script for " + std::to_string(*frames) + " frames"
                           : std::string("invalid motion script"));
  return script;
}

MotionScript MotionScript::load(const std::filesystem::path& path, std::optional<int> frames) {
  Expected<std::string> text = readTextFile(path);
  if (!text) throw MotionError(std::string(text.error().message()) + " (the motion script)");
  return parse(*text, path.string(), frames);
}

std::string MotionScript::presetYaml(const std::string& name) {
  const auto it = presets().find(name);
  if (it == presets().end()) {
    std::string known;
    for (const auto& n : presetNames()) known += " " + n;
    throw MotionError("unknown preset '" + detail::shown(name) + "' (known:" + known + ")");
  }
  return it->second;
}

MotionScript MotionScript::preset(const std::string& name) {
  return parse(presetYaml(name), "preset " + name);
}

std::vector<std::string> MotionScript::presetNames() {
  std::vector<std::string> names;
  for (const auto& [name, yaml] : presets()) names.push_back(name);
  return names;
}

std::vector<StampedPose> generateTrajectory(const MotionScript& script,
                                            const std::optional<Eigen::AlignedBox3d>& region) {
  detail::throwIfProblems("generateTrajectory: invalid script", script.validate());
  Generator g{std::mt19937_64(script.seed)};
  const int n = script.frameCount();
  std::vector<StampedPose> poses(n);
  poses[0].pose = Eigen::Isometry3d::Identity();
  std::size_t segment = 0;
  int step_in_segment = 0;
  double direction_sign = 1.0;
  for (int k = 1; k < n; ++k) {
    // Segments in order, cycled when the script asks for more frames than they hold.
    if (step_in_segment == script.segments[segment].frames) {
      segment = (segment + 1) % script.segments.size();
      step_in_segment = 0;
      direction_sign = 1.0;
    }
    const MotionSegment& s = script.segments[segment];
    const Eigen::Isometry3d& T_prev = poses[k - 1].pose;
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    if (s.rotation) {
      step.linear() = rotationFromVector(drawRotation(*s.rotation, g, step_in_segment,
                                                      T_prev.linear()));
    }
    if (s.translation) {
      step.translation() = drawTranslation(*s.translation, g, T_prev, region, direction_sign);
    }
    // Relative pose (R, t) = T_{k-1}^-1 * T_k (DESIGN.md section 2).
    poses[k].pose = T_prev * step;
    poses[k].timestamp = k / script.frame_rate;
    ++step_in_segment;
  }
  if (const std::optional<VibrationSignal> vibration = script.vibrationSignal()) {
    for (auto& p : poses) p.pose.linear() = p.pose.linear() * vibration->rotation(p.timestamp);
  }
  return poses;
}

}  // namespace omnipose::synth
