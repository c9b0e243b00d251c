#include "omnipose/odometry.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>

#include "common/problem_list.hpp"
#include "imu/gyro_buffer.hpp"
#include "omnipose/so3.hpp"
#include "pipeline/capture_time_offset.hpp"
#include "pipeline/frame_registrar.hpp"
#include "pipeline/gyro_bias.hpp"
#include "pipeline/gyro_fusion.hpp"
#include "pipeline/loop_closure.hpp"
#include "pipeline/plausibility.hpp"
#include "pipeline/readout_yaw.hpp"

namespace omnipose {
namespace {

using Clock = std::chrono::steady_clock;

/// Gyro samples Odometry keeps (8 s at 1 kHz).
constexpr std::size_t kGyroSamplesKept = 8192;

/// Largest rotation between the chained pose and a keyframe's estimate of it that anchors the
/// pose, radians (1.1 deg): a chain drifts from its keyframe by a small fraction of that
/// while the keyframe is in reach, so more is a registration gone wrong (an aliased texture,
/// a person in front of the camera).
constexpr double kMaxAnchorCorrection = 0.02;

/// Why a frame after a rejected one is rejected too when the ring search cannot place it.
const Error kNotFoundAgain(ErrorCode::kImplausible,
                           "implausible frame: after a frame that was not believed, nothing of the "
                           "last believed frame is found in it (the whole-ring search failed)");

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

/// `T` with its rotation projected back onto SO(3). The chain composes every pose from the
/// keyframe's (K * (K^-1 * predicted)), and an Isometry's inverse is its transpose, so a
/// rounding error in K's orthogonality would double at every such step.
Eigen::Isometry3d orthonormalized(const Eigen::Isometry3d& T) {
  Eigen::Isometry3d out = T;
  out.linear() = Eigen::Quaterniond(T.linear()).normalized().toRotationMatrix();
  return out;
}

/// A pair translated when the fit's translation is both significant and large enough for the
/// images' yaw to drift with it. Significant: tau^T C^-1 tau above the 99.9 % point of a
/// chi-square with three degrees of freedom. Large enough: |tau| above a thousandth of the
/// scene's distance a pair (2.5 mm a frame at 2.5 m); the drift, about 0.03 mrad a pair at
/// |tau| 0.007 on the drift benchmark's rectangle, is then below a twentieth of a pair's
/// noise. Turning in place with vibration and a rolling shutter the fit finds |tau| below
/// 0.0003, often "significant"; driving at 2 cm a frame, 0.0065-0.009, tau^T C^-1 tau
/// 800-4000.
constexpr double kTranslatingChi2 = 16.3;
constexpr double kTranslatingTau = 1e-3;

/// Whether the pair of the fit `e` translated (above); by |tau| alone when its covariance
/// does not tell (a method that gives none).
bool translates(const MotionEstimate& e) {
  if (!(e.tau.norm() > kTranslatingTau)) return false;
  const Eigen::Matrix3d C = e.covariance.bottomRightCorner<3, 3>();
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(C);
  if (!C.allFinite() || ldlt.info() != Eigen::Success || !ldlt.isPositive() ||
      !(C.diagonal().minCoeff() > 0.0))
    return true;
  return !(e.tau.dot(ldlt.solve(e.tau)) <= kTranslatingChi2);
}

/// The motion `T` (pose of the frame in the reference) as a FrameMotion.
void setMotion(FrameMotion& m, const Eigen::Isometry3d& T) {
  m.has_motion = true;
  m.rotation = T.linear();
  m.estimate.omega = rotationVector(m.rotation);
  m.estimate.tau = T.translation();
  m.tau_norm = m.estimate.tau.norm();
  m.translation_direction =
      m.tau_norm > 0.0 ? Eigen::Vector3d(m.estimate.tau / m.tau_norm) : Eigen::Vector3d::Zero();
}

}  // namespace

const char* toString(TrackState state) {
  switch (state) {
    case TrackState::kSegmentStart: return "start";
    case TrackState::kTracked: return "tracked";
    case TrackState::kBridged: return "bridged";
    case TrackState::kLost: return "lost";
    case TrackState::kGyroBridged: return "gyro";
  }
  return "?";
}

std::vector<std::string> KeyframeOptions::validate() const {
  std::vector<std::string> problems;
  detail::checkRange(problems, "slots", slots, 0, WindowRegistration::kMaxKeyframeSlots,
                     " (0 = no keyframes)");
  if (!(max_translation >= 0.0 && max_translation <= 1.0))
    problems.push_back("max_translation: " + std::to_string(max_translation) +
                       " is outside [0, 1] scene distances");
  if (!(max_tilt_rad >= 0.0 && max_tilt_rad <= 0.5))
    problems.push_back("max_tilt_rad: " + std::to_string(max_tilt_rad) + " rad (" +
                       std::to_string(max_tilt_rad * 180.0 / std::numbers::pi) +
                       " deg) is outside [0, 0.5] radians ([0, 28.6] degrees)");
  if (!(anchor_gain >= 0.0 && anchor_gain <= 1.0))
    problems.push_back("anchor_gain: " + std::to_string(anchor_gain) + " is outside [0, 1]");
  detail::checkRange(problems, "anchor_interval", anchor_interval, 1, 100, " frames");
  if (!(min_ring_peak > 0.0 && min_ring_peak < 1.0))
    problems.push_back("min_ring_peak: " + std::to_string(min_ring_peak) + " is outside (0, 1)");
  if (!(gap_after_s >= 0.0 && gap_after_s <= 3600.0))
    problems.push_back("gap_after_s: " + std::to_string(gap_after_s) +
                       " is outside [0, 3600] seconds (0 = only reported gaps)");
  return problems;
}

std::vector<std::string> LoopClosureOptions::validate() const {
  std::vector<std::string> problems;
  detail::checkRange(problems, "max_places", max_places, 2, 1024, " places");
  if (!(place_spacing > 0.0 && place_spacing <= 1.0))
    problems.push_back("place_spacing: " + std::to_string(place_spacing) +
                       " is outside (0, 1] scene distances");
  if (!(search_radius >= place_spacing && search_radius <= 10.0))
    problems.push_back("search_radius: " + std::to_string(search_radius) +
                       " is outside [place_spacing, 10] scene distances");
  if (!(min_similarity >= 0.0 && min_similarity < 1.0))
    problems.push_back("min_similarity: " + std::to_string(min_similarity) + " is outside [0, 1)");
  if (!(max_correction_rad > 0.0 && max_correction_rad <= 0.5))
    problems.push_back("max_correction_rad: " + std::to_string(max_correction_rad) +
                       " is outside (0, 0.5] radians");
  detail::checkRange(problems, "check_interval", check_interval, 1, 100, " frames");
  detail::checkRange(problems, "confirmations", confirmations, 1, 10, "");
  if (!(max_turn_rate_rad_s > 0.0 && max_turn_rate_rad_s <= 100.0))
    problems.push_back("max_turn_rate_rad_s: " + std::to_string(max_turn_rate_rad_s) +
                       " is outside (0, 100] rad/s");
  return problems;
}

std::vector<std::string> PlausibilityOptions::validate() const {
  std::vector<std::string> problems;
  if (!(max_repeated_rows >= 0.0 && max_repeated_rows <= 1.0))
    problems.push_back("max_repeated_rows: " + std::to_string(max_repeated_rows) +
                       " is outside [0, 1]");
  if (!(min_confidence_ratio >= 0.0 && min_confidence_ratio < 1.0))
    problems.push_back("min_confidence_ratio: " + std::to_string(min_confidence_ratio) +
                       " is outside [0, 1)");
  if (!(max_rotation_rad_s > 0.0 && max_rotation_rad_s <= 100.0 * std::numbers::pi))
    problems.push_back("max_rotation_rad_s: " + std::to_string(max_rotation_rad_s) +
                       " rad/s is outside (0, 314] (0 to 18000 deg/s)");
  detail::checkRange(problems, "max_rejected", max_rejected, 1, 1000, " frames");
  return problems;
}

std::vector<std::string> OdometryOptions::validate() const {
  std::vector<std::string> problems;
  for (const auto& p : pipeline.validate()) problems.push_back("pipeline." + p);
  for (const auto& p : keyframes.validate()) problems.push_back("keyframes." + p);
  for (const auto& p : plausibility.validate()) problems.push_back("plausibility." + p);
  for (const auto& p : loop_closure.validate()) problems.push_back("loop_closure." + p);
  return problems;
}

std::vector<std::string> Odometry::validate(const Calibration& calibration,
                                            const OdometryOptions& options) {
  std::vector<std::string> problems;
  for (const auto& p : Pipeline::validate(calibration, options.pipeline))
    problems.push_back(p.starts_with("calibration") ? p : "pipeline." + p);
  for (const auto& p : options.keyframes.validate()) problems.push_back("keyframes." + p);
  for (const auto& p : options.plausibility.validate()) problems.push_back("plausibility." + p);
  for (const auto& p : options.loop_closure.validate()) problems.push_back("loop_closure." + p);
  return problems;
}

struct Odometry::Impl {
  /// A kept keyframe: its frame and its chained pose in the current segment.
  struct Keyframe {
    bool valid = false;
    std::int64_t sequence = -1;
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    long last_used = 0;
    double time_s = 0.0;  ///< its frame's timestamp
    pipeline::ReadoutYaw::Anchor heading;  ///< its place in the rolling shutter's yaw chain
  };

  Impl(const Calibration& c, const OdometryOptions& o)
      : gyro_calibration(c.imu),
        measure_yaw_capture_time(o.pipeline.yaw_capture_time),
        fuse_gyro(o.pipeline.gyro_fusion),
        keyframe_options(o.keyframes),
        plausibility_options(o.plausibility),
        registrar(std::in_place, c, o.pipeline,
                  std::max(o.keyframes.slots, 1) + (o.loop_closure.enabled ? 1 : 0)),
        gate(std::in_place, o.plausibility, inputFrameSize(c, o.pipeline.unwrap.input).height,
             registrar->windowCount()),
        keyframes(static_cast<std::size_t>(std::max(o.keyframes.slots, 1))),
        lens_grid(map::LensGrid::of(c)),
        readout_yaw(registrar->meanWindowTime()) {
    // The slot after the keyframes' is the loop closure's, for the places it compares.
    if (o.loop_closure.enabled)
      loop.emplace(o.loop_closure, *registrar, static_cast<int>(keyframes.size()),
                   o.keyframes.min_ring_peak);
  }
  explicit Impl(std::unique_ptr<MotionEstimator> method)
      : keyframe_options{.slots = 0}, pairwise(std::move(method)) {}

  Expected<OdometryResult> process(const cv::Mat& frame, const FrameStamp& stamp);
  Expected<OdometryResult> processPairwise(const cv::Mat& frame, OdometryResult& out);

  /// The current frame starts a segment: its pose is held, it becomes the only keyframe.
  void startSegment(OdometryResult& out, TrackState state);
  /// Registration of the current frame after a gap or a lost fit: ring search and fit
  /// against the last keyframe. False when it fails; kImplausible when the frame is not
  /// believed (PlausibilityGate).
  Expected<bool> bridge(OdometryResult& out);
  /// The current frame is not believed (`why`): it is dropped and the next one bridged, or,
  /// after PlausibilityOptions::max_rejected such frames in a row, it starts a new segment.
  Expected<OdometryResult> rejectFrame(OdometryResult& out, const Error& why);
  /// bridge(); when it fails, a new segment, or a rejection right after a rejected frame.
  Expected<OdometryResult> bridgeOrRestart(OdometryResult& out);
  /// The total time, segment and keyframe distance of `out`, and its map pose when
  /// placeOnMap() has not given it yet.
  void finishTiming(OdometryResult& out);
  /// The map pose of the current frame at odometry pose out.pose (LoopClosure): `measured`,
  /// a frame tracked with its refined windows (its panorama still the registrar's current
  /// one), is placed and compared with the places; any other is held.
  void placeOnMap(OdometryResult& out, bool measured);
  /// The current frame was believed with the motion in `out`.
  void believe(const OdometryResult& out) {
    if (!gate) return;
    const auto& e = out.relative.estimate;
    gate->believe(out.relative.has_motion &&
                  (e.omega.norm() > pipeline::PlausibilityGate::kMovedThreshold ||
                   e.tau.norm() > pipeline::PlausibilityGate::kMovedThreshold));
  }
  /// The kept keyframe to refine against at the predicted pose `predicted` of the current
  /// frame: the last one used while it is in reach, else the oldest in reach; -1 for none.
  int chooseKeyframe(const Eigen::Isometry3d& predicted) const;
  bool inReach(const Keyframe& k, const Eigen::Isometry3d& predicted) const;
  /// Registers the current frame against keyframe `slot` as well (from the pose `T` that
  /// the pair's refinement `pair` gave, `first` the first pass) and moves `T`
  /// KeyframeOptions::anchor_gain of the way to the keyframe's estimate. False, `T`
  /// unchanged, when that registration fails, is not kOk, or disagrees with `T` by more
  /// than kMaxAnchorCorrection (the keyframe is no longer a view to trust).
  bool anchorToKeyframe(int slot, const MotionEstimate& first, const pipeline::PassResult& pair,
                        Eigen::Isometry3d& T);
  /// Makes the previous frame (the current one after advance()) a keyframe, in the least
  /// recently used slot.
  void addKeyframe(const Eigen::Isometry3d& pose);
  void useKeyframe(int slot) {
    active = slot;
    keyframes[static_cast<std::size_t>(slot)].last_used = ++use_clock;
  }
  /// The row timing of a registration of the current frame against a frame captured at
  /// `reference_time`; `pair`: against the previous frame, whose motion's velocity is known
  /// when that frame was tracked.
  void setShutter(double reference_time, bool pair) {
    pipeline::ShutterContext c;
    c.interval_s = time - reference_time;
    if (pair && velocity_interval > 0.0) {
      c.previous_velocity = velocity;
      c.previous_interval_s = velocity_interval;
    }
    if (gyro_calibration && registrar->rowsMoveWithinFrame(exposure))
      c.gyro_rotation = gyroRotation(reference_time);
    registrar->setShutter(c);
  }
  /// The camera's rotation from `reference_time` to the current frame's from the gyro (its
  /// bias as estimated removed); nullopt without a gyro or where its samples do not tell.
  std::optional<Eigen::Matrix3d> gyroRotation(double reference_time) const {
    if (!gyro_calibration) return std::nullopt;
    return integrateGyro(gyro.samples(), *gyro_calibration, gyro_bias.bias(), reference_time,
                         time, gyroMaxGap());
  }
  /// The images' rotation from the last good frame to the current one (`images`, from the
  /// fit `fit`, whose covariance and translation go with it), a reading of the gyro's bias
  /// and, when the pass took the rows' turns from the gyro (`gyro_rows`), of the time the
  /// windows' yaw was captured at (CaptureTimeOffset; the next frames' passes read it there).
  void updateFromGyro(const Eigen::Matrix3d& images, const MotionEstimate& fit, bool gyro_rows) {
    const std::optional<Eigen::Matrix3d> G = gyroRotation(last_time);
    if (!G) return;
    if (gyro_rows && measure_yaw_capture_time &&
        capture_offset.update(rotationVector(G->transpose() * images).z(),
                              yawRateNow() - last_yaw_rate, capture_offset.offset()))
      registrar->setYawTimeOffset(capture_offset.offset());
    const double dt = time - last_time;
    const pipeline::GyroBiasReading reading{
        images, fit.covariance.topLeftCorner<3, 3>(), *G,
        pipeline::gyroRotationVariance(gyroNoiseDensity(), 0.0, dt), dt, translates(fit)};
    if (gyro_bias.update(reading, gyro_calibration->rotation.normalized().toRotationMatrix()))
      ++gyro_counters.bias_readings;
  }
  /// The gyro's yaw rate at the current frame's timestamp (rad/s, camera axes), NaN where
  /// its samples do not tell or without a gyro.
  double yawRateNow() const {
    if (!gyro_calibration) return std::numeric_limits<double>::quiet_NaN();
    const std::optional<Eigen::Vector3d> rate =
        gyroRateAt(gyro.samples(), *gyro_calibration, gyro_bias.bias(), time, gyroMaxGap());
    return rate ? rate->z() : std::numeric_limits<double>::quiet_NaN();
  }
  /// The current frame after a gap the images could not bridge, with the gyro's rotation
  /// since the last good frame: kGyroBridged, the frame a keyframe. False without one.
  bool gyroBridge(OdometryResult& out);
  /// Two samples further apart than this are a gap, seconds.
  double gyroMaxGap() const { return kGyroGapIntervals * gyro.typicalInterval(); }
  /// The exposure the current frame is modelled with: `stated` (FrameStamp::exposure_s)
  /// when it is a usable number of seconds, else the calibration's (a refusal counted).
  double frameExposure(double stated) {
    const SensorTiming& sensor = registrar->calibration().sensor;
    const double exposure = sensor.exposureOf(stated);
    if (exposure >= 0.0 && exposure <= SensorTiming::kMaxExposureS) return exposure;
    ++gyro_counters.exposures_refused;
    return sensor.exposure_s;
  }
  /// The current frame's rows' rotations from the gyro, counted.
  void measureRowRotations() {
    if (!gyro_calibration) return;
    if (!registrar->rowsMoveWithinFrame(exposure)) {
      registrar->forgetRowRotations();
      return;
    }
    if (registrar->measureRowRotations(gyro.samples(), *gyro_calibration, gyro_bias.bias(),
                                       time, gyroMaxGap(), exposure))
      ++gyro_counters.frames_with_gyro;
    else
      ++gyro_counters.frames_without_gyro;
  }
  /// The rotation of `pass`, a registration of the current frame against the frame captured
  /// at `reference_time`, with its yaw moved from the windows' mean capture times to the
  /// timestamps (a rolling shutter; unchanged for a global shutter; `key`: the keyframe
  /// registered against, whose place in the yaw chain it continues). Against the previous
  /// frame, the motion as registered, per second, becomes the next pair's previous velocity
  /// (read at the same mean capture times as the next fit's own).
  Eigen::Matrix3d atTimestamps(const pipeline::PassResult& pass, double reference_time,
                               const Keyframe* key = nullptr) {
    const double interval = time - reference_time;
    if (reference_time == last_time && interval > 0.0) {
      velocity << rotationVector(pass.rotation), pass.estimate.tau;
      velocity /= interval;
      velocity_interval = interval;
    } else {
      velocity_interval = 0.0;
    }
    if (pass.gyro_rows) {
      // Already between the timestamps; a pair without the gyro later starts a chain anew.
      readout_yaw.reset();
      return pass.rotation;
    }
    return readout_yaw.betweenTimestamps(pass.rotation, reference_time, time,
                                         key != nullptr ? &key->heading : nullptr);
  }
  /// A pair's rotation as the images alone measured it, and their fit of the pair.
  struct PairRotation {
    Eigen::Matrix3d rotation;
    const MotionEstimate& estimate;
  };
  /// Fills `out` for the current frame at pose `T` with the estimate `pass`.
  /// `images`: the pair's rotation as the images alone measured it, for the gyro's bias (the
  /// rotation of T from the last frame's pose and the fit of `pass` when null).
  void finish(OdometryResult& out, const Eigen::Isometry3d& T, const pipeline::PassResult& pass,
              TrackState state, const PairRotation* images = nullptr);

  std::optional<ImuCalibration> gyro_calibration;  ///< the calibration's imu section
  imu::GyroBuffer gyro{kGyroSamplesKept};
  pipeline::GyroBias gyro_bias;
  /// PipelineOptions::yaw_capture_time: capture_offset measured and used.
  bool measure_yaw_capture_time = false;
  /// PipelineOptions::gyro_fusion.
  bool fuse_gyro = false;
  /// The variance per axis of the gyro's rotation from `reference_time` to the current frame,
  /// rad^2: its white noise (a phone-class gyro's when the calibration does not give it) and
  /// the bias's uncertainty, at most `max_bias_sigma` rad/s, over the interval (infinity
  /// without a gyro or before its bias is known).
  double gyroVariance(double reference_time,
                      double max_bias_sigma = std::numeric_limits<double>::infinity()) const {
    if (!gyro_calibration) return std::numeric_limits<double>::infinity();
    return pipeline::gyroRotationVariance(
        gyroNoiseDensity(), std::min(gyro_bias.sigma(), max_bias_sigma), time - reference_time);
  }
  /// The gyro's white noise, rad/s/sqrt(Hz): the calibration's, or a phone-class gyro's.
  double gyroNoiseDensity() const {
    return gyro_calibration && gyro_calibration->gyro_noise_density
               ? *gyro_calibration->gyro_noise_density
               : pipeline::kPhoneGyroNoiseDensity;
  }
  /// With PipelineOptions::gyro_fusion: `R` (the images' rotation from `reference_time` to
  /// the current frame) and `estimate` combined with the gyro's rotation over the same
  /// interval (gyro_fusion.hpp); unchanged without a gyro, before its bias has settled
  /// (GyroBias::settled()) or where its samples do not tell.
  void fuseGyro(double reference_time, Eigen::Matrix3d& R, MotionEstimate& estimate) const {
    if (!fuse_gyro || !gyro_bias.settled()) return;
    if (const std::optional<Eigen::Matrix3d> G = gyroRotation(reference_time))
      pipeline::fuseGyroRotation(R, estimate, *G, gyroVariance(reference_time));
  }
  pipeline::CaptureTimeOffset capture_offset;
  /// The gyro's yaw rate at the last good frame's timestamp (yawRateNow() then).
  double last_yaw_rate = std::numeric_limits<double>::quiet_NaN();
  GyroCounters gyro_counters;
  KeyframeOptions keyframe_options;
  PlausibilityOptions plausibility_options;
  std::optional<pipeline::FrameRegistrar> registrar;  ///< the iFMI pipeline
  std::optional<pipeline::PlausibilityGate> gate;     ///< with the iFMI pipeline
  std::unique_ptr<MotionEstimator> pairwise;          ///< or another per-pair method
  std::vector<Keyframe> keyframes;
  std::optional<pipeline::LoopClosure> loop;  ///< the map (LoopClosureOptions::enabled)
  map::LensGrid lens_grid;  ///< the calibration's, kept with the map (map_file.hpp)
  bool frame_mapped = false;                  ///< placeOnMap() ran for the current frame
  pipeline::ReadoutYaw readout_yaw;  ///< chains the pairs' yaws (rolling shutter)
  int active = -1;  ///< slot of the keyframe the last frame used
  /// Frames with another keyframe in reach since the last keyframe registration
  /// (KeyframeOptions::anchor_interval).
  int frames_since_anchor = 0;
  long use_clock = 0;

  bool started = false;  ///< a frame of the current segment has been processed
  bool gap = false;      ///< the link to the last good frame is broken
  int segment = -1;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< last good frame's
  std::int64_t last_sequence = -1;
  double last_time = 0.0;  ///< capture time of the last good frame
  /// The last pair's motion as registered (omega, translation in scene distances) per second
  /// and its interval when that frame was tracked against the one before; interval 0
  /// otherwise.
  Eigen::Matrix<double, 6, 1> velocity = Eigen::Matrix<double, 6, 1>::Zero();
  double velocity_interval = 0.0;
  double time = 0.0;       ///< of the frame being processed
  double exposure = 0.0;   ///< the exposure of the frame being processed, seconds
  std::int64_t auto_sequence = 0;
  std::int64_t sequence = -1;  ///< the frame being processed
  Clock::time_point t_start;
};

void Odometry::Impl::startSegment(OdometryResult& out, TrackState state) {
  ++segment;
  started = true;
  gap = false;
  for (auto& k : keyframes) k.valid = false;
  frames_since_anchor = 0;
  out.state = state;
  out.relative = FrameMotion{};
  readout_yaw.begin(time);
  if (registrar) {
    registrar->makeCurrentPrevious();
    addKeyframe(pose);
    out.keyframe_sequence = sequence;
  }
  out.pose = pose;
  last_sequence = sequence;
  last_time = time;
  velocity_interval = 0.0;
  if (gate) {
    gate->restart();
    gate->believe(false);
  }
}

bool Odometry::Impl::inReach(const Keyframe& k, const Eigen::Isometry3d& predicted) const {
  if (!k.valid) return false;
  const Eigen::Isometry3d relative = k.pose.inverse() * predicted;
  return relative.translation().norm() <= keyframe_options.max_translation &&
         tiltAngle(relative.linear()) <= keyframe_options.max_tilt_rad;
}

int Odometry::Impl::chooseKeyframe(const Eigen::Isometry3d& predicted) const {
  if (keyframe_options.slots == 0) return -1;
  if (active >= 0 && inReach(keyframes[static_cast<std::size_t>(active)], predicted)) return active;
  int best = -1;
  for (int i = 0; i < static_cast<int>(keyframes.size()); ++i) {
    if (inReach(keyframes[static_cast<std::size_t>(i)], predicted) &&
        (best < 0 || keyframes[i].sequence < keyframes[static_cast<std::size_t>(best)].sequence))
      best = i;
  }
  return best;
}

void Odometry::Impl::addKeyframe(const Eigen::Isometry3d& at) {
  int slot = 0;
  for (int i = 1; i < static_cast<int>(keyframes.size()); ++i) {
    const Keyframe& k = keyframes[static_cast<std::size_t>(i)];
    const Keyframe& s = keyframes[static_cast<std::size_t>(slot)];
    if (!k.valid ? s.valid : (s.valid && k.last_used < s.last_used)) slot = i;
  }
  if (!registrar->storeKeyframe(slot)) return;
  keyframes[static_cast<std::size_t>(slot)] = {true, sequence, at, 0, time, readout_yaw.anchor()};
  useKeyframe(slot);
}

void Odometry::Impl::finish(OdometryResult& out, const Eigen::Isometry3d& T_estimated,
                            const pipeline::PassResult& pass, TrackState state,
                            const PairRotation* images) {
  const Eigen::Isometry3d T = orthonormalized(T_estimated);
  if (gyro_calibration && state == TrackState::kTracked && pass.estimate.status == FitStatus::kOk)
    updateFromGyro(images != nullptr ? images->rotation : pose.linear().transpose() * T.linear(),
                   images != nullptr ? images->estimate : pass.estimate, pass.gyro_rows);
  out.state = state;
  const FrameMotion keep_timing = out.relative;
  out.relative.estimate = pass.estimate;
  setMotion(out.relative, pose.inverse() * T);
  out.relative.timing = keep_timing.timing;
  out.reference_sequence = last_sequence;
  out.windows_reference_sequence = pass.windows.empty() ? -1 : last_sequence;
  out.windows = pass.windows;
  out.window_weights = pass.window_weights;
  out.windows_refined = pass.refined;
  out.window_model = pass.window_model;
  pose = T;
  out.pose = T;
  last_sequence = sequence;
  last_time = time;
  last_yaw_rate = yawRateNow();
}

Expected<bool> Odometry::Impl::bridge(OdometryResult& out) {
  if (active < 0) return false;
  const Keyframe& key = keyframes[static_cast<std::size_t>(active)];
  setShutter(key.time_s, false);
  // The rotation from the keyframe: the gyro's across the gap when it has one (the last good
  // frame's pose from the keyframe's, then the gyro), else the yaw of the whole-ring search.
  std::optional<MotionEstimate> aligned;
  Eigen::Matrix3d R0 = Eigen::Matrix3d::Identity();
  if (const std::optional<Eigen::Matrix3d> G = gyroRotation(last_time)) {
    R0 = key.pose.linear().transpose() * pose.linear() * *G;
    aligned = registrar->alignedPass(R0, active);
  }
  if (!aligned || aligned->status == FitStatus::kLost) {
    const std::optional<double> yaw = registrar->ringYaw(active, keyframe_options.min_ring_peak);
    if (!yaw) return false;
    R0 = rotationFromVector(Eigen::Vector3d(0.0, 0.0, *yaw));
    aligned = registrar->alignedPass(R0, active);
  }
  if (!aligned || aligned->status == FitStatus::kLost) return false;
  const pipeline::PassResult pass = registrar->refine(
      *aligned, rotationFromVector(aligned->omega) * R0, aligned->tau, active);
  if (!pass.refined || pass.estimate.status == FitStatus::kLost) return false;
  if (Expected<void> ok = gate->checkConfidence(pass.windows, pass.estimate.status); !ok)
    return std::unexpected(ok.error());
  const double turned = rotationVector(pass.rotation).norm();
  if (Expected<void> ok = gate->checkRotation(turned, time - key.time_s); !ok)
    return std::unexpected(ok.error());
  const Eigen::Isometry3d T =
      key.pose * isometry(atTimestamps(pass, key.time_s, &key), pass.estimate.tau);
  out.keyframe_sequence = key.sequence;
  useKeyframe(active);
  registrar->makeCurrentPrevious();
  finish(out, T, pass, TrackState::kBridged);
  out.windows_reference_sequence = key.sequence;
  velocity_interval = 0.0;  // a motion across a gap says little about the next pair's
  // Without keyframes the one slot follows the last good frame: this one.
  if (keyframe_options.slots == 0) addKeyframe(pose);
  gap = false;
  believe(out);
  return true;
}

bool Odometry::Impl::gyroBridge(OdometryResult& out) {
  const std::optional<Eigen::Matrix3d> G = gyroRotation(last_time);
  if (!G) return false;
  pipeline::PassResult pass;
  pass.rotation = *G;
  pass.estimate.omega = rotationVector(*G);
  pass.estimate.tau.setZero();
  pass.estimate.status = FitStatus::kDegraded;
  pass.estimate.covariance.setZero();
  // The rotation's variance over the gap, the bias's uncertainty taken as at most 0.02 rad/s.
  pass.estimate.covariance.topLeftCorner<3, 3>().diagonal().setConstant(
      gyroVariance(last_time, 0.02));
  pass.estimate.covariance.bottomRightCorner<3, 3>().diagonal().setConstant(
      std::numeric_limits<double>::infinity());
  registrar->makeCurrentPrevious();
  finish(out, pose * isometry(*G, Eigen::Vector3d::Zero()), pass, TrackState::kGyroBridged);
  out.keyframe_sequence = sequence;
  addKeyframe(pose);
  readout_yaw.reset();
  velocity_interval = 0.0;
  gap = false;
  ++gyro_counters.frames_gyro_bridged;
  gate->restart();  // a view of its own: the confidences before it say nothing of it
  gate->believe(false);
  return true;
}

Expected<OdometryResult> Odometry::Impl::rejectFrame(OdometryResult& out, const Error& why) {
  if (gate->rejectedInARow() >= plausibility_options.max_rejected) {
    // The view changed for good: the gyro's rotation across, or start again from here.
    if (!gyroBridge(out)) startSegment(out, TrackState::kLost);
    finishTiming(out);
    return out;
  }
  // Nothing of the frame is kept: the previous frame stays the last believed one, and the
  // next frame is registered against it (the whole-ring search when that fails, or after
  // gap_after_s).
  gate->reject();
  return std::unexpected(why);
}

Expected<OdometryResult> Odometry::Impl::bridgeOrRestart(OdometryResult& out) {
  const auto t_bridge = Clock::now();
  const Expected<bool> bridged = bridge(out);
  if (!bridged) return rejectFrame(out, bridged.error());
  if (!*bridged) {
    // Right after a frame that was not believed, a frame that cannot be found again is more
    // of the glitch (until max_rejected); after an outage or a source that started over it
    // is a view of its own: a new segment.
    if (gate->rejectedInARow() > 0) return rejectFrame(out, kNotFoundAgain);
    if (!gyroBridge(out)) startSegment(out, TrackState::kLost);
  }
  out.relative.timing.refine = secondsSince(t_bridge);
  finishTiming(out);
  return out;
}

void Odometry::Impl::placeOnMap(OdometryResult& out, bool measured) {
  frame_mapped = true;
  if (!loop) {
    out.map_pose = out.pose;
    return;
  }
  pipeline::LoopClosure::Update u;
  if (measured) {
    pipeline::LoopClosure::Frame f;
    f.sequence = sequence;
    f.time_s = time;
    f.odometry = out.pose;
    f.turn_rate = velocity.head<3>().norm();
    f.yaw_rate = velocity(2);
    u = loop->update(f);
  } else {
    u = loop->hold(out.pose, out.state != TrackState::kBridged);
  }
  out.map_pose = u.map_pose;
  out.map_correction = u.correction;
  out.loop_closed = u.loop_closed;
  out.loop_place_sequence = u.place_sequence;
  out.places = loop->places();
  out.relocalising = loop->relocalising();
}

void Odometry::Impl::finishTiming(OdometryResult& out) {
  if (!frame_mapped) placeOnMap(out, false);
  out.relative.timing.total = secondsSince(t_start);
  out.segment = segment;
  if (out.keyframe_sequence >= 0)
    out.frames_since_keyframe = static_cast<int>(sequence - out.keyframe_sequence);
}

Expected<OdometryResult> Odometry::Impl::process(const cv::Mat& frame, const FrameStamp& stamp) {
  t_start = Clock::now();
  frame_mapped = false;
  sequence = stamp.sequence >= 0 ? stamp.sequence : auto_sequence;
  auto_sequence = sequence + 1;
  time = stamp.time_s;
  if (stamp.gap_before) gap = true;
  if (started && keyframe_options.gap_after_s > 0.0 &&
      !(std::abs(stamp.time_s - last_time) <= keyframe_options.gap_after_s))
    gap = true;  // a hole in the stream, or time going back: the motion since is unknown
  OdometryResult out;
  out.sequence = sequence;
  if (pairwise) return processPairwise(frame, out);

  exposure = frameExposure(stamp.exposure_s);
  pipeline::FrameRegistrar& r = *registrar;
  const auto burst = r.frameBurst();
  FrameMotion& m = out.relative;
  if (auto ok = r.unwrap(frame); !ok) {
    gap = true;
    return std::unexpected(ok.error());
  }
  measureRowRotations();
  m.timing.unwrap = secondsSince(t_start);
  const Expected<void> frame_ok = gate->checkFrame(frame);

  if (!started) {
    startSegment(out, TrackState::kSegmentStart);
    finishTiming(out);
    return out;
  }
  if (!frame_ok) return rejectFrame(out, frame_ok.error());
  if (gap) return bridgeOrRestart(out);

  // First pass against the previous frame (after a frame that was not believed: the last
  // believed one, the previous frame still).
  const auto t_reg = Clock::now();
  setShutter(last_time, true);
  const std::optional<MotionEstimate> first = r.firstPass(&m.timing.fit);
  if (!first) {
    gap = true;
    return fail(ErrorCode::kInvalidArgument, "window registration rejected the panorama");
  }
  m.timing.registration = secondsSince(t_reg) - m.timing.fit;
  const auto t_refine = Clock::now();
  // A lost fit: the motion since the previous frame is unknown.
  if (first->status == FitStatus::kLost) return bridgeOrRestart(out);
  // After a frame that was not believed the motion since the last believed one may be beyond
  // a window's reach: then the whole-ring search decides.
  const auto notBelieved = [&](const Error& why) {
    return gate->rejectedInARow() > 0 ? bridgeOrRestart(out) : rejectFrame(out, why);
  };
  if (Expected<void> ok = gate->checkRotation(first->omega.norm(), time - last_time); !ok)
    return notBelieved(ok.error());

  // The pair's motion: the refinement against the previous frame.
  const Eigen::Matrix3d R1 = rotationFromVector(first->omega);
  setShutter(last_time, true);
  const pipeline::PassResult pass =
      r.refine(*first, R1, first->tau, WindowRegistration::kPreviousFrame);
  if (Expected<void> ok = gate->checkConfidence(pass.windows, pass.estimate.status); !ok)
    return notBelieved(ok.error());
  const Eigen::Matrix3d images = atTimestamps(pass, last_time);
  pipeline::PassResult fused = pass;
  Eigen::Matrix3d R = images;
  fuseGyro(last_time, R, fused.estimate);
  Eigen::Isometry3d T = pose * isometry(R, fused.estimate.tau);
  // The pose, anchored to the keyframe in reach; with none (or one that no longer registers)
  // the frame becomes a keyframe.
  const int slot = chooseKeyframe(T);
  bool keep_keyframe = false;
  if (slot >= 0) {
    if (keyframes[static_cast<std::size_t>(slot)].sequence == last_sequence ||
        ++frames_since_anchor < keyframe_options.anchor_interval) {
      keep_keyframe = true;
    } else {
      frames_since_anchor = 0;
      keep_keyframe = anchorToKeyframe(slot, *first, pass, T);
    }
  }
  out.keyframe_sequence = keep_keyframe ? keyframes[static_cast<std::size_t>(slot)].sequence
                                        : last_sequence;
  if (keep_keyframe) useKeyframe(slot);
  r.advance();
  const PairRotation images_alone{images, pass.estimate};
  finish(out, T, fused, TrackState::kTracked, &images_alone);
  believe(out);
  // Before addKeyframe(), which takes the current panorama.
  placeOnMap(out, pass.refined && velocity_interval > 0.0);
  // Without keyframes (slots 0) the one slot follows the previous frame.
  if (!keep_keyframe) addKeyframe(pose);
  m.timing.refine = secondsSince(t_refine);
  finishTiming(out);
  return out;
}

bool Odometry::Impl::anchorToKeyframe(int slot, const MotionEstimate& first,
                                      const pipeline::PassResult& pair, Eigen::Isometry3d& T) {
  if (keyframe_options.anchor_gain == 0.0) return true;  // kept for gaps only
  const Keyframe& key = keyframes[static_cast<std::size_t>(slot)];
  const Eigen::Isometry3d from_key = key.pose.inverse() * T;
  setShutter(key.time_s, false);
  const pipeline::PassResult pass =
      registrar->secondRefine(first, from_key.linear(), from_key.translation(), slot);
  if (!pass.refined || pass.estimate.status != FitStatus::kOk) return false;
  // Its rotation between the timestamps: the gyro's rows, or the yaw chain's offsets at the
  // keyframe and at this frame (set by the pair's registration).
  std::optional<Eigen::Matrix3d> R;
  if (pass.gyro_rows == pair.gyro_rows)
    R = pass.gyro_rows ? std::optional(pass.rotation)
                       : readout_yaw.againstAnchor(pass.rotation, key.heading);
  if (!R) return false;
  MotionEstimate from_keyframe = pass.estimate;
  fuseGyro(key.time_s, *R, from_keyframe);
  const Eigen::Isometry3d d = T.inverse() * (key.pose * isometry(*R, from_keyframe.tau));
  const Eigen::Vector3d correction = rotationVector(d.linear());
  if (correction.norm() > kMaxAnchorCorrection) return false;
  const double gain = keyframe_options.anchor_gain;
  T = T * isometry(rotationFromVector(gain * correction), gain * d.translation());
  return true;
}

Expected<OdometryResult> Odometry::Impl::processPairwise(const cv::Mat& frame,
                                                         OdometryResult& out) {
  Expected<FrameMotion> motion = pairwise->process(frame);
  if (!motion) return std::unexpected(motion.error());
  const StageTiming timing = motion->timing;
  if (!motion->has_motion) {
    startSegment(out, TrackState::kSegmentStart);
  } else if (motion->estimate.status == FitStatus::kLost) {
    startSegment(out, TrackState::kLost);
  } else {
    pipeline::PassResult pass;
    pass.estimate = motion->estimate;
    pass.rotation = motion->rotation;
    pass.window_model = motion->estimate.vector();
    finish(out, pose * isometry(motion->rotation, motion->estimate.tau), pass, TrackState::kTracked);
  }
  out.relative.timing = timing;
  out.segment = segment;
  out.map_pose = out.pose;  // no map: the pairwise methods' poses are their odometry
  return out;
}

Odometry::Odometry(const Calibration& calibration, const OdometryOptions& options) {
  detail::throwIfProblems("invalid odometry configuration", validate(calibration, options));
  impl_ = std::make_unique<Impl>(calibration, options);
}

Odometry::Odometry(std::unique_ptr<MotionEstimator> pairwise) {
  if (!pairwise) throw std::invalid_argument("Odometry: no motion estimator");
  impl_ = std::make_unique<Impl>(std::move(pairwise));
}

Odometry::~Odometry() = default;

Expected<OdometryResult> Odometry::process(const cv::Mat& frame, const FrameStamp& stamp) {
  return impl_->process(frame, stamp);
}

void Odometry::addGyro(std::span<const GyroSample> samples) {
  Impl& s = *impl_;
  if (!s.gyro_calibration) return;
  GyroCounters& c = s.gyro_counters;
  for (const GyroSample& sample : samples) {
    switch (s.gyro.push(sample)) {
      case imu::GyroIntake::kAccepted: ++c.accepted; break;
      case imu::GyroIntake::kNotFinite: ++c.not_finite; break;
      case imu::GyroIntake::kTooFast: ++c.too_fast; break;
      case imu::GyroIntake::kOutOfOrder: ++c.out_of_order; break;
      case imu::GyroIntake::kClockRestart:
        ++c.accepted;
        ++c.clock_restarts;
        break;
    }
  }
}

LoopClosureCounters Odometry::loopClosureCounters() const {
  return impl_->loop ? impl_->loop->counters() : LoopClosureCounters{};
}

GyroCounters Odometry::gyroCounters() const {
  GyroCounters c = impl_->gyro_counters;
  c.bias = impl_->gyro_bias.bias();
  c.bias_sigma = impl_->gyro_bias.sigma();
  c.yaw_time_offset_s = impl_->capture_offset.offset();
  if (!impl_->gyro.samples().empty()) c.last_sample_t = impl_->gyro.samples().back().t;
  return c;
}

void Odometry::markGap() {
  impl_->gap = true;
  ++impl_->auto_sequence;
}

void Odometry::reset() {
  Impl& s = *impl_;
  s.started = false;
  s.gap = false;
  s.segment = -1;
  s.pose = Eigen::Isometry3d::Identity();
  s.last_sequence = -1;
  s.auto_sequence = 0;
  s.active = -1;
  for (auto& k : s.keyframes) k.valid = false;
  if (s.loop) s.loop->clear();
  if (s.registrar) s.registrar->forgetPrevious();
  if (s.gate) s.gate->restart();
  if (s.pairwise) s.pairwise->reset();
}

const char* Odometry::methodName() const {
  return impl_->pairwise ? impl_->pairwise->name() : "ifmi";
}
int Odometry::threads() const { return impl_->registrar ? impl_->registrar->threads() : 1; }
int Odometry::activeThreads() const {
  return impl_->registrar ? impl_->registrar->activeThreads() : 1;
}
double Odometry::workerWaitSeconds() const {
  return impl_->registrar ? impl_->registrar->workerWaitSeconds() : 0.0;
}

std::int64_t Odometry::framesWaitedForWorkers() const {
  return impl_->registrar ? impl_->registrar->framesWaitedForWorkers() : 0;
}
bool Odometry::wisdomLoaded() const {
  return impl_->registrar && impl_->registrar->wisdomLoaded();
}
int Odometry::windowCount() const {
  return impl_->registrar ? impl_->registrar->windowCount() : 0;
}
bool Odometry::snapshotMap(map::MapSnapshot& out) const {
  if (!impl_->loop) return false;
  impl_->loop->snapshot(out);
  out.lens = impl_->lens_grid;
  return true;
}
Expected<void> Odometry::restoreMap(const map::MapSnapshot& snapshot) {
  if (!impl_->loop)
    return std::unexpected(Error(ErrorCode::kInvalidArgument, "there is no map: loop closure is off"));
  return impl_->loop->restore(snapshot);
}
double Odometry::windowAttenuation() const {
  return impl_->registrar ? impl_->registrar->windowAttenuation() : 1.0;
}

}  // namespace omnipose
