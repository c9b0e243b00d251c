#include "pipeline/readout_yaw.hpp"

#include <cmath>
#include <limits>

#include "omnipose/so3.hpp"

namespace omnipose::pipeline {

void ReadoutYaw::begin(double t) {
  ++chain_;
  samples_ = 1;
  time_[2] = t;
  heading_[2] = 0.0;
}

Eigen::Matrix3d ReadoutYaw::betweenTimestamps(const Eigen::Matrix3d& R, double t_ref,
                                              double t_cur, const Anchor* reference) {
  const double dt = t_cur - t_ref;
  if (offset_ == 0.0 || !(dt > 0.0)) {
    reset();
    return R;
  }
  Eigen::Vector3d omega = rotationVector(R);
  const double measured = omega.z();  // heading(t_cur + c) - heading(t_ref + c)
  // With the velocity constant over the pair, the heading at a timestamp is the sample
  // there less c times the velocity.
  const double constant_velocity = -offset_ * measured / dt;
  // The reference frame: the chain's last one, an anchor of this chain before it, or else
  // the first frame of a new chain.
  const bool last = samples_ > 0 && t_ref == time_[2];
  const bool anchored = !last && samples_ > 0 && reference != nullptr &&
                        reference->chain == chain_ && reference->time == t_ref &&
                        t_cur > time_[2];
  if (!last && !anchored) begin(t_ref);
  double reference_sample = heading_[2], reference_offset = offset_heading_;
  if (anchored) {
    reference_sample = reference->sample;
    reference_offset = offsetOf(*reference);
  } else if (samples_ == 1) {
    // The chain's first pair: the first frame's offset at constant velocity, kept for
    // later pairs against it.
    reference_offset = origin_offset_ = constant_velocity;
  }
  for (int i = 0; i < 2; ++i) {
    time_[i] = time_[i + 1];
    heading_[i] = heading_[i + 1];
  }
  time_[2] = t_cur;
  heading_[2] = reference_sample + measured;
  samples_ = samples_ < 3 ? samples_ + 1 : 3;

  double at_timestamp = constant_velocity;
  if (samples_ == 3) {
    // The parabola through the three samples (at time_[i] + c), at t_cur (Lagrange), less
    // the newest sample; the samples relative to it, so that the sum stays small.
    at_timestamp = 0.0;
    for (int a = 0; a < 2; ++a) {
      double weight = 1.0;
      for (int b = 0; b < 3; ++b) {
        if (b != a) weight *= (t_cur - time_[b] - offset_) / (time_[a] - time_[b]);
      }
      at_timestamp += weight * (heading_[a] - heading_[2]);
    }
  }
  // heading(t_cur) - heading(t_ref) = measured + (offset at t_cur) - (offset at t_ref).
  omega.z() += at_timestamp - reference_offset;
  offset_heading_ = at_timestamp;
  return rotationFromVector(omega);
}

std::optional<Eigen::Matrix3d> ReadoutYaw::againstAnchor(const Eigen::Matrix3d& R,
                                                         const Anchor& reference) const {
  if (offset_ == 0.0) return R;
  if (samples_ < 2 || reference.chain != chain_ || !(reference.time < time_[2])) return std::nullopt;
  Eigen::Vector3d omega = rotationVector(R);
  omega.z() += offset_heading_ - offsetOf(reference);
  return rotationFromVector(omega);
}

ReadoutYaw::Anchor ReadoutYaw::anchor() const {
  if (samples_ == 0) return {};
  return {chain_, time_[2], heading_[2],
          samples_ == 1 ? std::numeric_limits<double>::quiet_NaN() : offset_heading_};
}

}  // namespace omnipose::pipeline
