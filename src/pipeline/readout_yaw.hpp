#pragma once
/// \file readout_yaw.hpp
/// Yaw between the frames' timestamps under a rolling shutter (private to the core library;
/// DESIGN.md section 3, "Rolling shutter").
///
/// A registration of two rolling-shutter frames reads yaw from the part of du common to every
/// window, so over [t_ref + c, t_cur + c], c being the windows' mean capture time after the
/// frame's timestamp (FrameRegistrar::meanWindowTime()). What would tell the rows read early
/// from those read late (du's first harmonic around the ring) a horizontal translation also
/// makes, so a pair alone cannot give the yaw between its timestamps. Registrations chain
/// those yaws into samples of the heading at t_k + c; the heading at a timestamp t_k lies
/// between two of them (0 < c < t_k - t_(k-1)) and is read off the parabola through the last
/// three samples: exact for a constant angular acceleration at any frame spacing, and nothing
/// accumulates (the published headings are the chained samples moved by their own offsets).
/// The first pair of a chain takes the velocity as constant, which leaves its yaw as measured.
/// A keyframe keeps its place in the chain (Anchor), so that registrations against it
/// continue the chain instead of beginning one at each frame.
///
/// Realtime: no allocation, never throws.

#include <Eigen/Core>
#include <cmath>
#include <optional>

namespace omnipose::pipeline {

class ReadoutYaw {
 public:
  /// A frame's place in a chain, for registrations against it from a later frame than the
  /// next (a keyframe): its timestamp, its heading sample at time + c (radians, on the
  /// chain's own scale) and its published heading minus that sample (NaN for the chain's
  /// first frame before any pair: set by the chain's first pair).
  struct Anchor {
    long chain = -1;  ///< -1: none
    double time = 0.0, sample = 0.0, offset = 0.0;
  };

  /// `capture_offset_s`: c, seconds; 0 (a global shutter) leaves every rotation unchanged.
  explicit ReadoutYaw(double capture_offset_s = 0.0) : offset_(capture_offset_s) {}

  /// Forgets the chain: the next pair starts a new one.
  void reset() { samples_ = 0; }
  /// Starts a new chain at the frame captured at `t` (seconds): a segment's first frame,
  /// whose anchor() later pairs may be registered against.
  void begin(double t);

  /// `R`: a registration's relative rotation (camera frame of t_ref to that of t_cur), its
  /// yaw (the rotation vector's z, the camera's vertical) between t_ref + c and t_cur + c,
  /// its roll and pitch between the timestamps (the pair's own tilt-rate regression).
  /// Returns R with its yaw moved to between t_ref and t_cur, roll and pitch unchanged. The
  /// frame at t_ref is the chain's last one (t_ref = the last call's t_cur) or `reference`,
  /// an anchor() of this chain taken when that frame was the last one; otherwise (or when
  /// t_cur is not after the chain's last frame) the pair begins a new chain at t_ref.
  /// Times in seconds; with no offset or t_cur <= t_ref, R is returned as is and the chain
  /// is forgotten.
  Eigen::Matrix3d betweenTimestamps(const Eigen::Matrix3d& R, double t_ref, double t_cur,
                                    const Anchor* reference = nullptr);

  /// `R`: a second registration of the chain's last frame (the last betweenTimestamps()'s
  /// t_cur, after a pair) against `reference`, an anchor() of this chain; R with its yaw
  /// moved to between the two timestamps as betweenTimestamps() would, the chain unchanged.
  /// R as is without an offset; nullopt when `reference` is not of this chain, is the last
  /// frame itself, or no pair has set the last frame's offset.
  std::optional<Eigen::Matrix3d> againstAnchor(const Eigen::Matrix3d& R,
                                               const Anchor& reference) const;

  /// The chain's last frame's anchor (chain -1 when no chain has begun or after reset()).
  Anchor anchor() const;

 private:
  /// The published heading minus the sample at the frame of `a`, an anchor of this chain (the
  /// chain's first frame's, set by its first pair, when the anchor was taken before it).
  double offsetOf(const Anchor& a) const { return std::isnan(a.offset) ? origin_offset_ : a.offset; }

  double offset_;
  long chain_ = -1;  ///< counts the chains begun
  /// The last samples of the chained heading, at times time_[i] + offset_, the newest last;
  /// samples_ of them.
  double time_[3] = {0.0, 0.0, 0.0};
  double heading_[3] = {0.0, 0.0, 0.0};
  int samples_ = 0;
  /// Published heading at time_[2] minus the sample there.
  double offset_heading_ = 0.0;
  /// The same for the chain's first frame, set by its first pair.
  double origin_offset_ = 0.0;
};

}  // namespace omnipose::pipeline
