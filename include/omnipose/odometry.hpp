#pragma once
/// \file odometry.hpp
/// The frame-to-pose policy of omnipose: timestamped frames in, per frame the motion since
/// the previous frame and the chained pose out. omniposed publishes what it returns and
/// omnipose-replay writes it to files, so what the accuracy benchmark measures is what the
/// daemon runs.
///
/// Keyframes (KeyframeOptions::slots > 0, the default). Every frame is registered against
/// the previous frame (a shift-only pass and a linear fit, then the refinement pass): that
/// is the pair's motion. While a keyframe other than the previous frame is in reach of the
/// pose it gives (KeyframeOptions: translation, tilt), the frame is registered against that
/// keyframe too, at that pose, and the pose is pulled towards the keyframe's estimate of it
/// (KeyframeOptions::anchor_gain): a robot that stands still or turns in place compares
/// every frame with the same keyframe, and the chain's error does not grow while the
/// keyframe holds. A frame with no keyframe in reach, or whose keyframe registration fails
/// or disagrees with the chain, becomes the new keyframe. A few recent keyframes are kept
/// (the least recently used one is replaced): when the robot turns or drives back, the
/// oldest one in reach is used again.
///
/// The map (LoopClosureOptions, on by default). Frames far from every place become places
/// (their panorama and a signature that does not change with the heading); when the robot
/// comes back, a frame near a place is registered against it and, verified and confirmed,
/// closes a loop: an edge of a pose graph over the places, solved again. `pose` is the
/// odometry's (REP-105 "odom": continuous, never corrected, what a controller integrates),
/// `map_pose` the corrected one ("map": it jumps when a loop closes). The map never changes
/// `pose`: it is the same with loop closure on or off.
///
/// Gaps. After a bad frame (process() returned an error), a gap the caller reports
/// (FrameStamp::gap_before: lost frames, a reconnect), a frame captured more than
/// KeyframeOptions::gap_after_s after the last good one, or a frame whose fit is lost, the
/// motion since the last good frame is unknown: the next frame is registered against the
/// keyframe, its yaw first found by a search over the whole ring (a circular correlation of
/// the panoramas), roll and pitch by the fit; with the robot's gyro (addGyro()) it starts
/// from the gyro's rotation across the gap instead. The chain goes on with the heading kept.
/// Only when that fails too does a new segment start (status kLost, segment + 1, the pose
/// held): the link across the gap is then unknown; where the gyro covers the gap, it bridges
/// it instead (kGyroBridged). A frame that decodes but cannot be
/// believed (PlausibilityOptions) is dropped and the next one registered against the last
/// believed frame; after max_rejected such frames in a row a new segment starts.
///
/// Realtime: the constructor allocates everything (worker threads, keyframe slots: each
/// holds the spectra of one panorama); process() allocates nothing and never throws. Not
/// thread-safe: one caller at a time.
///
/// Example: the motion between two images, tests/install/downstream/two_images.cpp (the
/// README shows it; the install test builds it against the installed package and runs it).

#include <Eigen/Geometry>
#include <cstdint>
#include <limits>
#include <memory>
#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/error.hpp"
#include "omnipose/gyro.hpp"
#include "omnipose/motion_estimator.hpp"
#include "omnipose/pipeline.hpp"
#include "omnipose/window_motion.hpp"

namespace omnipose {
namespace map {
struct MapSnapshot;  // src/map/map_file.hpp: the map as saved (private to the core library)
}  // namespace map

struct KeyframeOptions {
  /// Keyframes kept, the current one included (1..16; each holds a panorama's spectra,
  /// about 5 MB at the default window settings). 0 = no keyframes: the pose is the chain of
  /// the pairs' motions (a gap is still bridged against the last good frame).
  int slots = 4;
  /// A frame is refined against a keyframe only while the predicted translation from it is
  /// at most this, in scene distances (|t| / rho, the unit of MotionEstimate::tau): beyond
  /// it, parallax changes the view.
  double max_translation = 0.02;
  /// ... and while the predicted tilt from it (the angle between the two cameras' z axes:
  /// roll and pitch, not yaw) is at most this, radians: beyond it, rows leave the panorama.
  double max_tilt_rad = 0.09;
  /// How far each frame's pose is pulled from the frame-to-frame chain towards the pose its
  /// keyframe registration gives, [0, 1]. Every frame is refined against the previous frame
  /// (the pair's motion as exact as without keyframes) and, while a keyframe other than the
  /// previous frame is in reach, against that keyframe too; the chained pose is then moved
  /// this fraction of the way to the keyframe's estimate, so a drift of the chain from its
  /// keyframe decays by (1 - anchor_gain) per frame instead of adding up. 1 = the pose is
  /// the keyframe-relative estimate (each pair's motion then the difference of two such
  /// estimates, less exact); 0 = keyframes only for gaps.
  double anchor_gain = 0.1;
  /// The keyframe registration is made on one frame in this many while a keyframe is in
  /// reach, [1, 100]; the pose is pulled on those frames only. Each is a refinement pass,
  /// about half a frame's work (+46 % wall time per frame at rest or turning in place with
  /// 1, docs/PERFORMANCE.md), so a board short of CPU may trade: 3 with anchor_gain 0.3
  /// costs a third of that, its pairs 1-3 % less exact than with 1 on the rooms of
  /// docs/results/ANALYSIS.md ("Keyframes by default").
  int anchor_interval = 1;
  /// Whole-ring yaw search after a gap: the correlation peak below which the search has
  /// failed (a peak of ~0.01 is what unrelated panoramas give).
  double min_ring_peak = 0.03;
  /// A frame captured more than this after the last good frame (or before it) is treated
  /// as after a gap, seconds: frames missing without a word (a recording with a hole, a
  /// stalled camera) may hide a turn beyond a window's reach. 0 = only reported gaps.
  double gap_after_s = 0.15;

  /// One message per bad field, each starting with its name; empty when valid.
  std::vector<std::string> validate() const;
};

/// The place memory and its loop closures (DESIGN.md section 5, "Places and the map"). The
/// odometry's pose drifts; places seen before do not. Every place_spacing of travel a frame
/// becomes a place (its panorama and a signature that does not change with the heading);
/// when the robot comes back, a frame is compared with the places near its map pose
/// (signature first, then the whole-ring search and a full registration), and a match,
/// verified and confirmed, closes a loop: an edge of the pose graph over the places, which is
/// solved again. OdometryResult::pose stays the odometry's (continuous);
/// OdometryResult::map_pose is the corrected one, which jumps when a loop closes.
struct LoopClosureOptions {
  bool enabled = true;
  /// Places kept (each holds the panorama at 8 bits: 121 kB at the default 1100 x 110);
  /// when full, the least recently matched place is forgotten. [2, 1024].
  int max_places = 128;
  /// A frame becomes a place when no place lies within this of its map position, scene
  /// distances (|t| / rho), (0, 1].
  double place_spacing = 0.1;
  /// Places farther than this from the frame's map position are not compared with it, scene
  /// distances: the odometry's drift between two visits must stay within it, and a room
  /// that looks like one seen elsewhere is not taken for it. [place_spacing, 10].
  double search_radius = 0.3;
  /// Least signature similarity (cosine, [0, 1)) of a place worth a registration.
  double min_similarity = 0.9;
  /// Largest correction of the map pose's rotation a match may make, radians (0, 0.5]: the
  /// odometry's drift between two visits stays below it, a wrong match need not.
  double max_correction_rad = 0.1;
  /// A comparison with the places is made on one frame in this many, [1, 100] (each costs
  /// about a frame's work, and only when a place is in reach).
  int check_interval = 6;
  /// Matches in a row (on check frames, agreeing on the correction) that close a loop,
  /// [1, 10].
  int confirmations = 2;
  /// Frames turning faster than this neither become places nor are compared, rad/s: a
  /// rolling shutter and motion blur bend a turning frame's view.
  double max_turn_rate_rad_s = 0.5;

  /// One message per bad field, each starting with its name; empty when valid.
  std::vector<std::string> validate() const;
};

/// Frames that decode but cannot be believed: a glitching camera's torn, repeated,
/// flipped, rotated or foreign frame, or noise (DESIGN.md section 4, "Glitches"). Such a
/// frame is not chained: process() returns kImplausible (the daemon counts it as bad, the
/// replay skips it) and the next frame is found again against the last believed one (the
/// ring search when that fails). Tests: rows bit-identical to the previous frame's after a
/// pair that moved; the refined pass's median window confidence against the recent past;
/// the rotation rate.
struct PlausibilityOptions {
  bool enabled = true;
  /// Share of a frame's rows with content that may be bit-identical to the previous frame's
  /// after a pair that moved, [0, 1]. A sensor's noise makes every row differ.
  double max_repeated_rows = 0.25;
  /// A pair whose fit is not kOk and whose windows' median confidence is below this
  /// fraction of the median over the last believed pairs is not believed, [0, 1) (below
  /// 0.05 it never is). A flipped or foreign frame falls to about 0.04 of it; believed pairs
  /// stay above 0.85 of it on the benchmarks' renders and drop to 0.2 in motion blur.
  double min_confidence_ratio = 0.3;
  /// Fastest rotation the robot can make, radians per second (default 720 deg/s).
  double max_rotation_rad_s = 4.0 * 3.14159265358979323846;
  /// Frames rejected in a row after which the next one that fails starts a new segment
  /// instead (the view changed for good: a camera knocked aside, the light switched off),
  /// [1, 1000].
  int max_rejected = 5;

  /// One message per bad field, each starting with its name; empty when valid.
  std::vector<std::string> validate() const;
};

struct OdometryOptions {
  PipelineOptions pipeline;
  KeyframeOptions keyframes;
  PlausibilityOptions plausibility;
  LoopClosureOptions loop_closure;
  /// Every problem of the options, each starting with the field's path
  /// ("pipeline.registration.window: ...", "keyframes.slots: ..."); empty when valid.
  std::vector<std::string> validate() const;
};

/// What the caller knows of a frame besides its pixels.
struct FrameStamp {
  double time_s = 0.0;         ///< capture time of the frame, seconds (any epoch)
  std::int64_t sequence = -1;  ///< the frame's number (-1: numbered by the odometry)
  bool gap_before = false;     ///< frames were lost since the previous call (or a reconnect)
  /// How long each row of this frame was exposed, seconds, as the camera reported it (under
  /// auto-exposure it changes from frame to frame). NaN: not reported, the calibration's
  /// sensor.exposure_s holds. Only the gyro path reads it (DESIGN.md section 3, "Motion
  /// blur"); a value outside [0, SensorTiming::kMaxExposureS] is not used (the calibration's
  /// holds) and is counted (GyroCounters::exposures_refused).
  double exposure_s = std::numeric_limits<double>::quiet_NaN();
};

/// How a frame's pose was obtained.
enum class TrackState : std::int8_t {
  kSegmentStart = 0,  ///< first frame, or the first after a failed gap: no motion, pose held
  kTracked = 1,       ///< registered against the previous frame's prediction
  kBridged = 2,       ///< after a gap or a lost fit: found again against the keyframe
  kLost = 3,          ///< the fit failed and the gap could not be bridged: new segment
  /// The images could not bridge the gap, the robot's gyro did (Odometry::addGyro()): the
  /// motion's rotation is the gyro's, its translation unknown (zero, covariance infinite),
  /// status kDegraded; the frame becomes a keyframe and the chain goes on.
  kGyroBridged = 4,
};
const char* toString(TrackState state);

struct OdometryResult {
  TrackState state = TrackState::kSegmentStart;
  /// Frame's motion relative to the frame `reference_sequence` (the last good one): the
  /// difference of the two frames' poses (rotation, translation direction and |tau|), with
  /// the status, covariance (6 x 6 over (omega, tau)), residual and windows used of the
  /// registration that measured it (against the previous frame; after a gap against the
  /// keyframe). has_motion false at a segment start.
  FrameMotion relative;
  /// Chained pose of the frame (camera to segment origin; positions in scene distances).
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  int segment = 0;                        ///< 0 for the first, +1 at every new segment
  std::int64_t sequence = -1;             ///< this frame's
  std::int64_t reference_sequence = -1;   ///< the frame the motion is relative to; -1 at a start
  /// The keyframe the pose was anchored to (KeyframeOptions::anchor_gain), or bridged from
  /// after a gap; reference_sequence when the frame had no other keyframe in reach (it then
  /// becomes one).
  std::int64_t keyframe_sequence = -1;
  int frames_since_keyframe = 0;          ///< frames from that keyframe to this one
  /// The frame `windows` were registered against: reference_sequence, or after a gap the
  /// keyframe; -1 without windows.
  std::int64_t windows_reference_sequence = -1;
  /// The windows of the pass that made the estimate (valid until the next process()), and
  /// the motion that pass fitted to them (relative to the panorama it registered, which is
  /// de-rotated after a refinement: Eq. 3's model gives each window's fitted du/dv).
  std::span<const WindowMotion> windows;
  /// How much each of `windows` weighed in that pass's fit, relative to the heaviest (1);
  /// 0 for a window left out (beyond the inlier threshold, invalid, masked). Valid until the
  /// next process(); empty when `windows` is.
  std::span<const double> window_weights;
  bool windows_refined = false;  ///< the windows are the refinement pass's (de-rotated)
  Eigen::Matrix<double, 6, 1> window_model = Eigen::Matrix<double, 6, 1>::Zero();

  /// The pose in the map frame (REP-105's "map"; `pose` is its "odom"): map_correction *
  /// pose, the odometry's pose corrected by the loop closures so far (LoopClosureOptions).
  /// It jumps on a frame that closes a loop (loop_closed) and moves with `pose` otherwise;
  /// equal to `pose` until the first closure and without loop closure.
  Eigen::Isometry3d map_pose = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d map_correction = Eigen::Isometry3d::Identity();  ///< map from odom
  bool loop_closed = false;  ///< this frame closed a loop: map_pose jumped
  /// The place this frame was matched with when it closed a loop (its frame's sequence),
  /// else -1.
  std::int64_t loop_place_sequence = -1;
  int places = 0;  ///< places in the memory
  /// The map was loaded (Odometry::restoreMap()) and this frame's place in it is not found
  /// yet: map_pose is the odometry's pose; the frame that finds it closes a loop.
  bool relocalising = false;

  /// A pose with motion (kTracked, kBridged or kGyroBridged).
  bool tracked() const {
    return state == TrackState::kTracked || state == TrackState::kBridged ||
           state == TrackState::kGyroBridged;
  }
};

/// What became of the gyro samples given to Odometry::addGyro(), and of the frames that could
/// have used them. Counts since construction.
struct GyroCounters {
  std::int64_t accepted = 0;      ///< samples kept (a clock restart's first included)
  std::int64_t not_finite = 0;    ///< refused: a NaN or infinite time or rate
  std::int64_t too_fast = 0;      ///< refused: a rate beyond kMaxGyroRate
  std::int64_t out_of_order = 0;  ///< refused: stamped at or before the sample before it
  /// The IMU's clock jumped back by more than a second (a restarted driver or board): the
  /// samples before the jump were dropped and the stream taken up again from there.
  std::int64_t clock_restarts = 0;
  /// Frames (rolling shutter, calibration with an imu section) whose rows' rotations came
  /// from the gyro, and frames the samples did not cover (a gap, a stream that stopped or
  /// has not caught up): those are registered from the images alone.
  std::int64_t frames_with_gyro = 0;
  std::int64_t frames_without_gyro = 0;
  /// Gaps the images could not bridge and the gyro did (TrackState::kGyroBridged).
  std::int64_t frames_gyro_bridged = 0;
  /// Frame pairs whose images' rotation updated the gyro's bias estimate.
  std::int64_t bias_readings = 0;
  /// Frames whose stated exposure (FrameStamp::exposure_s) was not a number of seconds in
  /// [0, SensorTiming::kMaxExposureS]: modelled with the calibration's instead.
  std::int64_t exposures_refused = 0;
  /// The gyro's bias as estimated from the images, rad/s about the IMU's axes (zero before
  /// any reading), and one standard deviation of it (infinite before two readings).
  Eigen::Vector3d bias = Eigen::Vector3d::Zero();
  double bias_sigma = 0.0;
  /// With a rolling shutter or an exposure: how much later than their modelled capture times
  /// the windows' yaw is read, seconds, as measured against the gyro (0 until told from 0;
  /// DESIGN.md section 3, "Rolling shutter with a gyro").
  double yaw_time_offset_s = 0.0;
  /// The newest sample kept, seconds on the IMU's clock; NaN before any.
  double last_sample_t = std::numeric_limits<double>::quiet_NaN();
};

/// What the map (LoopClosureOptions) made of the frames it compared with its places, counts
/// since construction: how often a place was registered against a frame, and which test
/// refused each match that closed nothing. All zero without a map.
struct LoopClosureCounters {
  /// Registrations of a frame against a place (a loop-closure check that found a place in
  /// reach like the frame; a relocalisation check, once per place it tries).
  std::int64_t compared = 0;
  std::int64_t no_ring_peak = 0;  ///< refused: the whole-ring search found no clear heading
  /// Refused: the ring's or the fit's heading farther than max_correction_rad from the map's
  /// prediction (from the ring's, relocalising): a look-alike turned, or a wrong peak.
  std::int64_t turned_too_far = 0;
  std::int64_t fit_failed = 0;    ///< refused: not a kOk fit of most windows
  std::int64_t too_far = 0;       ///< refused: the fit puts the frame beyond search_radius
  std::int64_t verified = 0;      ///< matches that passed every test
  /// Relocalisation checks whose two places each matched the frame but disagreed on where
  /// the map puts it (a symmetric room, two identical rooms): the check counts for nothing.
  std::int64_t disagreed = 0;
  std::int64_t closures = 0;      ///< loops closed, loaded maps found included
};

class Odometry {
 public:
  /// Every problem that would stop the constructor (Pipeline::validate's, prefixed
  /// "pipeline.", and the keyframe options'); empty when valid.
  static std::vector<std::string> validate(const Calibration& calibration,
                                           const OdometryOptions& options);
  /// The iFMI pipeline with keyframes. Throws std::invalid_argument listing every problem.
  Odometry(const Calibration& calibration, const OdometryOptions& options);
  /// Chains another per-pair method (a feature baseline): the same gap and segment policy,
  /// without keyframes or ring search (a frame after a gap is paired with the last good one).
  explicit Odometry(std::unique_ptr<MotionEstimator> pairwise);
  ~Odometry();
  Odometry(const Odometry&) = delete;
  Odometry& operator=(const Odometry&) = delete;

  /// Processes the next frame. An error (kBadFrame: wrong size or type, black;
  /// kImplausible: a glitch, PlausibilityOptions) leaves the state as it was, and the next
  /// frame is treated as after a gap.
  Expected<OdometryResult> process(const cv::Mat& frame, const FrameStamp& stamp);
  /// Gyro samples (stamped on the IMU's clock, calibration.yaml `imu` joins it to the
  /// frames'), in the order they arrive; call it before process() with the samples up to the
  /// frame's last row (later ones do no harm). With a rolling shutter each row's rotation
  /// within its frame then comes from the gyro, the pair's rotation from the images
  /// (DESIGN.md section 3, "Rolling shutter with a gyro"); a frame the samples do not cover
  /// is registered from the images alone (GyroCounters). With any shutter the images track
  /// the gyro's bias, a gap is searched for from the gyro's rotation across it, and a gap
  /// the images cannot bridge is bridged by the gyro (TrackState::kGyroBridged; DESIGN.md
  /// section 3, "The gyro's bias and bridging"). A bad sample (GyroCounters) is refused and
  /// counted, never an error. Ignored without an imu section in the calibration and for a
  /// pairwise method. Keeps the last 8192 samples (8 s at 1 kHz); allocates nothing.
  void addGyro(std::span<const GyroSample> samples);
  GyroCounters gyroCounters() const;
  /// The map's comparisons and why they closed nothing (LoopClosureCounters).
  LoopClosureCounters loopClosureCounters() const;

  /// Reports a frame that could not be read (decode error): the next frame is bridged.
  void markGap();
  /// Forgets everything: the next frame starts segment 0 again at the identity.
  void reset();

  const char* methodName() const;
  /// The iFMI pipeline's threads (1 for a pairwise method's chaining).
  int threads() const;
  /// Time process() has spent waiting for its worker threads since construction, seconds:
  /// for a job's last indices, still running on a worker, after the calling thread ran out
  /// of its own. Small on a machine with cores to spare; it grows when other processes take
  /// the workers' cores (0 with one thread and for a pairwise method).
  double workerWaitSeconds() const;
  /// Frames, since construction, in which the calling thread waited for a worker at least once
  /// (how often, where workerWaitSeconds() says how long; 0 with one thread).
  std::int64_t framesWaitedForWorkers() const;
  /// Threads (the calling one included) that take part in the next frame: threads(), or fewer
  /// while other processes' load on the machine made frames on fewer of them faster (measured
  /// frame by frame; 1 for a pairwise method).
  int activeThreads() const;
  /// Whether the FFTW wisdom file was read (false for a pairwise method).
  bool wisdomLoaded() const;
  /// Windows per panorama (0 for a pairwise method).
  int windowCount() const;

  /// The map (LoopClosureOptions) copied into `out` (src/map/map_file.hpp, for in-tree
  /// callers that save it from another thread). The first call makes room for the largest
  /// map; later ones allocate nothing. False without a map (loop closure off, a pairwise
  /// method).
  bool snapshotMap(map::MapSnapshot& out) const;
  /// Replaces the map with a saved one. Where the frames are in it is unknown until one is
  /// recognised (OdometryResult::relocalising; a loaded map that no frame recognises is
  /// dropped after the robot has moved and a new one begun: DESIGN.md section 5).
  /// kInvalidArgument, the map then empty, when it does not fit (another panorama size, more
  /// places than max_places) or there is no map.
  Expected<void> restoreMap(const map::MapSnapshot& snapshot);
  /// The motion model's window attenuation kappa (motion_model.hpp).
  double windowAttenuation() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace omnipose
