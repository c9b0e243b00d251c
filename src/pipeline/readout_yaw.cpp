#include "pipeline/readout_yaw.hpp"

#include "omnipose/so3.hpp"

namespace omnipose::pipeline {

Eigen::Matrix3d ReadoutYaw::betweenTimestamps(const Eigen::Matrix3d& R, double t_ref,
                                              double t_cur) {
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
  if (samples_ == 0 || t_ref != time_[2]) {
    samples_ = 1;
    time_[2] = t_ref;
    heading_[2] = 0.0;
    offset_heading_ = constant_velocity;
  }
  // The new sample, the others relative to it.
  for (int i = 0; i < 2; ++i) {
    time_[i] = time_[i + 1];
    heading_[i] = heading_[i + 1] - measured;
  }
  time_[2] = t_cur;
  heading_[2] = 0.0;
  samples_ = samples_ < 3 ? samples_ + 1 : 3;

  double at_timestamp = constant_velocity;
  if (samples_ == 3) {
    // The parabola through the three samples (at time_[i] + c), at t_cur (Lagrange).
    at_timestamp = 0.0;
    for (int a = 0; a < 3; ++a) {
      double weight = 1.0;
      for (int b = 0; b < 3; ++b) {
        if (b != a) weight *= (t_cur - time_[b] - offset_) / (time_[a] - time_[b]);
      }
      at_timestamp += weight * heading_[a];
    }
  }
  // heading(t_cur) - heading(t_ref) = measured + (offset at t_cur) - (offset at t_ref).
  omega.z() += at_timestamp - offset_heading_;
  offset_heading_ = at_timestamp;
  return rotationFromVector(omega);
}

}  // namespace omnipose::pipeline
