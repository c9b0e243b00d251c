#include "omnipose/pose_chain.hpp"

namespace omnipose {

void PoseChain::reset() {
  pose_.setIdentity();
  timestamp_ = 0.0;
  segment_ = -1;
  frames_ = 0;
}

const Eigen::Isometry3d& PoseChain::start(double timestamp) {
  ++segment_;
  ++frames_;
  timestamp_ = timestamp;
  return pose_;
}

const Eigen::Isometry3d& PoseChain::append(double timestamp, const Eigen::Matrix3d& R,
                                           const Eigen::Vector3d& t) {
  if (segment_ < 0) return start(timestamp);
  Eigen::Isometry3d rel = Eigen::Isometry3d::Identity();
  rel.linear() = R;
  rel.translation() = t;
  pose_ = pose_ * rel;
  // Keep the rotation orthonormal over long chains.
  pose_.linear() = Eigen::Quaterniond(pose_.rotation()).normalized().toRotationMatrix();
  timestamp_ = timestamp;
  ++frames_;
  return pose_;
}

}  // namespace omnipose
