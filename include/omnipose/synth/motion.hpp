#pragma once
/// \file motion.hpp
/// Motion scripts: per-frame rotation and translation steps, track vibration, and the
/// ground-truth trajectory they generate.

#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "omnipose/config_error.hpp"
#include "omnipose/io/trajectory.hpp"
#include "omnipose/synth/scene.hpp"

namespace omnipose::synth {

/// Per-frame rotation increment omega (the relative rotation R = exp([omega]x) of DESIGN.md
/// section 2, in the previous camera's frame).
struct RotationStep {
  /// x = roll, y = pitch, z = yaw (camera axes); random = direction uniform on the sphere.
  enum class Axis { kX, kY, kZ, kRandom };
  enum class Sign { kRandom, kAlternate, kPositive, kNegative };
  Axis axis = Axis::kZ;
  double min_deg = 1.0;  ///< |omega| drawn uniformly in [min_deg, max_deg], degrees
  double max_deg = 6.0;
  Sign sign = Sign::kRandom;  ///< sign of omega along a fixed axis (ignored for kRandom)
  /// If > 0: when a step would turn the camera more than bound_deg away from the start
  /// orientation (angle of the accumulated rotation), the opposite step is taken instead
  /// if that stays closer; keeps roll/pitch sequences bounded. Degrees.
  double bound_deg = 0.0;
};

/// Per-frame translation increment t (DESIGN.md section 2: the current camera's position in
/// the previous camera's frame).
struct TranslationStep {
  double min_m = 0.05;  ///< |t| drawn uniformly in [min_m, max_m], metres
  double max_m = 0.15;
  /// true: a uniformly random horizontal direction in the world frame; a step that would
  /// leave the allowed region is redrawn. false: `direction` in the camera frame; at the
  /// region's boundary the motion bounces (reverses for the rest of the segment).
  bool random_horizontal = true;
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();
};

/// Track vibration: a roll and pitch perturbation of the camera's attitude on top of the
/// scripted trajectory, as a tracked robot's chassis shakes on the ground. It does not
/// accumulate: frame k's pose is T_k = S_k * [R_vib(t_k) | 0], with S_k the scripted pose,
/// t_k = k / frame_rate and R_vib(t) = exp([roll(t), pitch(t), 0]x) (a rotation about the
/// camera centre; the position is the scripted one).
///
/// Each of roll and pitch is a sum of `components` sinusoids,
///   angle(t) = scale * sum_i w_i sin(2 pi f_i t + phi_i),
/// with weights w_i uniform in [0.5, 1], phases phi_i uniform in [0, 2 pi) and frequencies
/// f_i = m_i / D drawn without repetition from the whole numbers m_i of cycles over the
/// sequence's duration D = (frames - 1) / frame_rate whose frequency lies in
/// [min_hz, max_hz]. The vibration is therefore periodic over the sequence: it ends with the
/// attitude it began with, and its mean over frames 0 .. frames - 2 (one period) is zero.
/// `scale` makes the largest |angle(t_k)| over the sequence's frames exactly amplitude_deg.
/// Roll and pitch are drawn independently (roll first) from a generator seeded by `seed`
/// alone, so the scripted trajectory does not depend on the vibration.
struct Vibration {
  double amplitude_deg = 0.5;  ///< peak |roll| and peak |pitch| over the frames, degrees
  double min_hz = 1.0;         ///< lowest frequency, Hz
  double max_hz = 9.0;         ///< highest frequency, Hz (below half the frame rate)
  int components = 3;          ///< sinusoids per axis
  std::uint64_t seed = 0;

  /// One message per bad field (empty = valid), each starting with "vibration.<field>":
  /// amplitude_deg in (0, 10], 0 < min_hz <= max_hz, components in [1, 16].
  std::vector<std::string> validate() const;
};

/// One axis of a drawn vibration: angle(t) = scale_rad * sum_i weight[i] *
/// sin(2 pi frequency_hz[i] t + phase_rad[i]), radians.
struct VibrationAxis {
  std::vector<double> frequency_hz, phase_rad, weight;
  double scale_rad = 0.0;
  /// The angle at time t (seconds), radians.
  double angle(double t) const;
};

/// The vibration a script draws for its frames (see Vibration).
struct VibrationSignal {
  VibrationAxis roll, pitch;
  /// R_vib(t) = exp([roll.angle(t), pitch.angle(t), 0]x); t in seconds.
  Eigen::Matrix3d rotation(double t) const;
};

/// Draws the vibration of a sequence of `frames` frames at `frame_rate` Hz. Throws
/// std::invalid_argument naming the field when `vibration` is invalid, when frames < 2,
/// when max_hz is not below frame_rate / 2, or when the band holds fewer whole-cycle
/// frequencies over the sequence than `components`.
VibrationSignal drawVibration(const Vibration& vibration, int frames, double frame_rate);

/// `frames` consecutive increments, each with an optional rotation and translation.
struct MotionSegment {
  int frames = 1;
  std::optional<RotationStep> rotation;
  std::optional<TranslationStep> translation;
};

/// Thrown by MotionScript::load/parse: the configuration error, each problem naming the
/// file and the field (e.g. "m.yaml: segments[1].rotation.axis: 'w' is not x, y, z or random").
using MotionError = ConfigError;

/// A motion script. YAML format (every key but `segments` optional; defaults shown):
/// ```yaml
/// seed: 0                # random draws (steps, signs, directions)
/// frame_rate: 30.0       # Hz: frame i has timestamp i / frame_rate seconds
/// frames: 0              # total frames including the first; 0 = 1 + sum of segment frames,
///                        #   else the segments are cycled (or cut) to give exactly this many
/// wall_margin_m: 1.0     # box scene: the camera stays this far from the walls
/// vibration:             # optional track vibration (struct Vibration), on top of the segments
///   amplitude_deg: 0.5   #   peak |roll| and |pitch|, degrees
///   min_hz: 1            #   frequency band, Hz
///   max_hz: 9
///   components: 3        #   sinusoids per axis
///   seed: 0              #   its own random draws
/// walkers:               # optional people walking around the robot (struct Walkers)
///   count: 3             #   people, 0..100
///   width_m: 0.5         #   diameter, metres
///   height_m: 1.7        #   metres
///   base_z: -1.0         #   z of the feet, metres (default: the box room's floor)
///   speed_m_s: 1.2       #   walking speed along their circles, m/s
///   distance_m: [1.5, 2.0]   # circle radius about the world z axis, metres (or one number)
///   seed: 0              #   their own random draws
/// segments:
///   - frames: 50                 # increments in this segment
///     rotation:                  # optional
///       axis: z                  # x (roll) | y (pitch) | z (yaw) | random
///       step_deg: [1, 6]         # per-frame angle range, degrees (or one number)
///       sign: random             # random | alternate | positive | negative (fixed axes)
///       bound_deg: 0             # 0 = unbounded
///     translation:               # optional
///       step_m: [0.05, 0.15]     # per-frame distance range, metres (or one number)
///       direction: random_horizontal   # or [x, y, z] in the camera frame
/// ```
/// The scripted poses: S_0 = identity, S_k = S_{k-1} * [exp(omega_k), t_k]. Without
/// vibration T_k = S_k; with it T_k = S_k * [R_vib(t_k) | 0] (so T_0 = R_vib(0)).
struct MotionScript {
  std::uint64_t seed = 0;
  double frame_rate = 30.0;  ///< Hz
  int frames = 0;            ///< total frame count, 0 = 1 + sum of segment frames
  double wall_margin_m = 1.0;
  std::vector<MotionSegment> segments;
  std::optional<Vibration> vibration;  ///< track vibration, none by default
  /// People walking around (for Scene::walkers; the trajectory does not use them), none by
  /// default. validate() checks their fields; whether they fit a box room is checked where
  /// the scene is known (Walkers::validate(kind, box)).
  std::optional<Walkers> walkers;

  /// One message per bad field (empty = valid).
  std::vector<std::string> validate() const;
  /// Number of frames generateTrajectory() produces.
  int frameCount() const;
  /// The vibration generateTrajectory() applies (drawVibration() for frameCount() frames),
  /// or none. Throws std::invalid_argument like drawVibration().
  std::optional<VibrationSignal> vibrationSignal() const;
  /// Whether any segment translates (needs a box scene to be visible).
  bool translates() const;

  /// Reads a YAML motion script; throws MotionError listing every problem with the path.
  /// `frames`: replaces the script's `frames` before it is validated (what depends on the
  /// frame count, the vibration's band, is judged for that count).
  static MotionScript load(const std::filesystem::path& path, std::optional<int> frames = {});
  /// Parses YAML text; `origin` names the source in error messages; `frames` as in load().
  static MotionScript parse(const std::string& yaml_text, const std::string& origin = "<string>",
                            std::optional<int> frames = {});
  /// The paper's protocol: "roll", "pitch", "yaw" (100 frames, 1..6 deg per frame about
  /// one axis, random sign, roll/pitch bounded to 15 deg), "mixed" (100 frames, up to 12 deg
  /// per frame about a random axis, bounded to 20 deg), "translate" (100 frames, 5..15 cm
  /// horizontal steps in random directions plus up to 1 deg of rotation, box scene),
  /// "demo" (60 frames: yaw, roll, pitch, then translation). Throws MotionError naming
  /// the preset when unknown.
  static MotionScript preset(const std::string& name);
  /// The YAML text of a preset (what preset() parses).
  static std::string presetYaml(const std::string& name);
  /// Names of all presets.
  static std::vector<std::string> presetNames();
};

/// The camera poses T_world_camera of a script (the scripted poses times the vibration, if
/// any; see MotionScript), timestamps i / frame_rate. `region`: where the camera may be
/// (world frame); translation steps respect it (see TranslationStep). Throws MotionError if
/// no step keeps the camera inside the region, std::invalid_argument on an invalid script.
std::vector<StampedPose> generateTrajectory(const MotionScript& script,
                                            const std::optional<Eigen::AlignedBox3d>& region = {});

}  // namespace omnipose::synth
