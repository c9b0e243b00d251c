#pragma once
/// \file loop_closure.hpp
/// The map of Odometry (private to the core library): the place memory, the pose graph
/// over its places and the loop closures that join them (LoopClosureOptions; DESIGN.md
/// section 5, "Places and the map").
///
/// The map keeps an anchor: the place the odometry was last tied to, and the odometry's
/// pose of it (where the odometry would put that place now). A frame's map pose is the
/// anchor's pose in the graph moved by the odometry since the anchor. A frame far from
/// every place becomes a place (a node joined to the anchor by the odometry between them)
/// and the anchor. Every LoopClosureOptions::check_interval frames, a frame near a place
/// other than the anchor and its few newest places is compared with it: signature, then
/// the whole-ring search for the yaw, then a full registration (a shift-only pass and the
/// refinement against the place's panorama in a spare keyframe slot). The match is
/// verified (a kOk fit of most windows; the ring's yaw and the fit's rotation within
/// max_correction_rad of what the map predicts; the position within search_radius) and
/// confirmed (`confirmations` matches in a row that agree on the correction); then it is a
/// loop edge from the anchor to that place, the graph is solved again, and the place becomes
/// the anchor, at the pose the registration measured.
///
/// A map loaded from a file (restore()) is unanchored: where the odometry's frame lies in it
/// is unknown, so until a frame is recognised (relocalisation) the frames make no places and
/// their map pose is the odometry's. Every check_interval frames the frame is compared with
/// the kRelocaliseCandidates places most like it by signature, wherever they are, with the
/// yaw from the whole ring unconstrained; a match must pass verify()'s tests against the
/// ring's heading and lie within search_radius of its place, and when two places match, they
/// must agree on the map's correction. max(3, confirmations) matches in a row that agree on
/// the correction (rotation within 0.3 deg, position within place_spacing; a check with no
/// place like the frame breaks no row, one whose places fail does) anchor the map: a
/// loop closed, the map pose jumps to the loaded map's frame. After kRelocaliseChecks checks
/// without it, once the odometry has moved search_radius, the loaded map is dropped and a new
/// one begun.
///
/// Realtime: the constructor allocates everything; update() allocates nothing.

#include <Eigen/Geometry>
#include <cstdint>
#include <optional>

#include "map/map_file.hpp"
#include "map/place_memory.hpp"
#include "map/pose_graph.hpp"
#include "omnipose/odometry.hpp"
#include "pipeline/frame_registrar.hpp"

namespace omnipose::pipeline {

class LoopClosure {
 public:
  /// Registers against keyframe slot `spare_slot` of `registrar` (reserved for it).
  LoopClosure(const LoopClosureOptions& options, FrameRegistrar& registrar, int spare_slot,
              double min_ring_peak);

  /// A frame tracked by the odometry, its panorama the registrar's current one.
  struct Frame {
    std::int64_t sequence = -1;
    double time_s = 0.0;
    Eigen::Isometry3d odometry = Eigen::Isometry3d::Identity();  ///< its odometry pose
    double turn_rate = 0.0;  ///< |omega| of its pair per second, rad/s
    double yaw_rate = 0.0;   ///< the pair's turn rate about z, rad/s (rolling shutter)
  };
  /// What the map made of a frame.
  struct Update {
    Eigen::Isometry3d map_pose = Eigen::Isometry3d::Identity();
    Eigen::Isometry3d correction = Eigen::Isometry3d::Identity();  ///< map from odom
    bool loop_closed = false;
    std::int64_t place_sequence = -1;  ///< the place matched when loop_closed
  };
  /// Places the frame or compares it with the places (see the file comment); the
  /// registrar's passes against the spare slot overwrite its first-pass and second windows.
  Update update(const Frame& frame);
  /// A frame with no motion of its own (a segment start, a gap the gyro bridged): its map
  /// pose, no place made. `broken`: the odometry's link from the previous frame is unknown
  /// (a new segment), so the next place is joined to the anchor only loosely.
  Update hold(const Eigen::Isometry3d& odometry, bool broken);
  int places() const { return memory_.size(); }
  /// Since construction (clear() and restore() keep them).
  const LoopClosureCounters& counters() const { return counters_; }
  /// A loaded map not yet anchored (see the file comment).
  bool relocalising() const { return relocalising_; }
  void clear();
  /// Copies the map into `out` (map_file.hpp's takeSnapshot(): allocation-free once `out`
  /// has been used).
  void snapshot(map::MapSnapshot& out) const;
  /// Replaces the map with `snapshot`'s, unanchored (see the file comment); an empty one
  /// clears the map. kInvalidArgument, leaving the map empty, when it does not fit.
  Expected<void> restore(const map::MapSnapshot& snapshot);

  /// Places compared with a frame per relocalisation check, and the checks after which an
  /// unrecognised loaded map is dropped.
  static constexpr int kRelocaliseCandidates = 2;
  static constexpr int kRelocaliseChecks = 100;

 private:
  Eigen::Isometry3d correction() const;
  /// The place (not the anchor nor among the newest) to compare the frame at map pose
  /// `map_pose` with; -1 for none.
  int candidate(const Eigen::Isometry3d& map_pose);
  /// The frame's pose in place `id`'s frame (loaded in the spare slot) from a registration
  /// started at rotation `R0`: a kOk fit of most windows, or nullopt. Its rotation sigma into
  /// `rotation_sigma`.
  std::optional<Eigen::Isometry3d> registerAt(int id, const Eigen::Matrix3d& R0,
                                              const Frame& frame, double* rotation_sigma);
  /// The frame's pose in place `id`'s frame from the registration, verified against the
  /// map's prediction `predicted` (the same pose from the map); nullopt when it fails.
  std::optional<Eigen::Isometry3d> verify(int id, const Eigen::Isometry3d& predicted,
                                          const Frame& frame, double* rotation_sigma);
  /// A match closed a loop (or found a loaded map): place `id` becomes the anchor, the
  /// odometry putting it at `place_odometry`; `out` says so.
  void anchorAt(int id, const Eigen::Isometry3d& place_odometry, Update& out);
  /// Makes the frame a place (the least recently used one forgotten when full).
  void addPlace(const Frame& frame, const Eigen::Isometry3d& map_pose);
  bool nearAPlace(const Eigen::Isometry3d& map_pose) const;
  /// A relocalisation check (see the file comment); true when the map is anchored.
  bool relocalise(const Frame& frame, Update& out);
  /// The frame's pose in place `id`'s frame, its heading from the whole ring; nullopt when
  /// the registration fails, its rotation is farther than max_correction_rad from the ring's
  /// or it lies beyond search_radius.
  std::optional<Eigen::Isometry3d> recognise(int id, const Frame& frame);

  LoopClosureOptions options_;
  LoopClosureCounters counters_;
  FrameRegistrar& registrar_;
  int spare_slot_;
  double min_ring_peak_;
  map::PlaceMemory memory_;
  map::PlaceSignature signer_;
  map::PoseGraph graph_;
  map::PlaceSignature::Vector signature_{};
  long chain_serial_ = 0;  ///< PlaceMemory::stored() at the last loop closure
  int anchor_ = -1;
  Eigen::Isometry3d anchor_odometry_ = Eigen::Isometry3d::Identity();
  double anchor_distance_ = 0.0;  ///< odometry path length since the anchor (scene distances)
  long anchor_frames_ = 0;
  Eigen::Isometry3d last_odometry_ = Eigen::Isometry3d::Identity();
  bool loose_ = false;  ///< the odometry since the anchor crosses a broken link
  int frames_to_check_ = 0;
  /// Matches in a row and the correction (rotation vector, map frame) of the last one.
  int confirmed_ = 0;
  Eigen::Vector3d pending_correction_ = Eigen::Vector3d::Zero();
  bool relocalising_ = false;
  int relocalise_checks_ = 0;
  double relocalise_distance_ = 0.0;  ///< odometry path length since restore()
  Eigen::Isometry3d pending_map_ = Eigen::Isometry3d::Identity();  ///< the last match's correction
};

}  // namespace omnipose::pipeline
