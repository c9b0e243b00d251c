#pragma once
/// \file pose_chain.hpp
/// Chains relative poses into a trajectory: T_k = T_{k-1} * [R | t], with (R, t) the pose
/// of frame k in frame k-1 (P_{k-1} = R P_k + t). The first frame is at identity. A gap
/// (lost frames, failed fit) starts a new segment: the pose is held where it was and the
/// segment number increments, so consumers know the link across the gap is unknown
/// rather than being told the camera did not move. Positions are up to scale (units of
/// the scene distance rho). Allocation-free.

#include <Eigen/Geometry>

namespace omnipose {

class PoseChain {
 public:
  /// Forgets everything; the next frame is the first (identity, segment 0).
  void reset();
  /// Frame with no motion estimate before it: the first frame, or the first after a gap.
  /// Returns the (held) pose.
  const Eigen::Isometry3d& start(double timestamp);
  /// Frame k with its pose relative to frame k-1. Returns T_k.
  const Eigen::Isometry3d& append(double timestamp, const Eigen::Matrix3d& R,
                                  const Eigen::Vector3d& t);

  const Eigen::Isometry3d& pose() const { return pose_; }
  double timestamp() const { return timestamp_; }
  /// 0 for the first segment, +1 at every start() after the first.
  int segment() const { return segment_; }
  /// Frames in the chain so far (all segments).
  long frames() const { return frames_; }

 private:
  Eigen::Isometry3d pose_ = Eigen::Isometry3d::Identity();
  double timestamp_ = 0.0;
  int segment_ = -1;
  long frames_ = 0;
};

}  // namespace omnipose
