#include "pipeline/frame_rotation.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

#include "omnipose/so3.hpp"

namespace omnipose::pipeline {

FrameRotation::FrameRotation(double span_s) {
  const int pieces = std::max(1, static_cast<int>(std::ceil(std::abs(span_s) / kStepS)));
  step_ = std::abs(span_s) / pieces;
  turn_.assign(static_cast<std::size_t>(pieces) + 1, Eigen::Vector3d::Zero());
  rate_ = turn_;
}

bool FrameRotation::measure(std::span<const GyroSample> samples, const ImuCalibration& imu,
                            const Eigen::Vector3d& bias, double time, double max_gap_s) {
  known_ = false;
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  for (std::size_t i = 0; i < turn_.size(); ++i) {
    const double at = time + static_cast<double>(i) * step_;
    if (i > 0) {
      const std::optional<Eigen::Matrix3d> piece =
          integrateGyro(samples, imu, bias, at - step_, at, max_gap_s);
      if (!piece) return false;
      R = R * *piece;
    }
    const std::optional<Eigen::Vector3d> rate = gyroRateAt(samples, imu, bias, at, max_gap_s);
    if (!rate) return false;
    turn_[i] = rotationVector(R);
    rate_[i] = *rate;
  }
  known_ = true;
  return true;
}

Eigen::Vector3d FrameRotation::turnAt(double s) const {
  const std::size_t last = turn_.size() - 1;
  if (!(s > 0.0)) return turn_.front() + rate_.front() * s;
  if (step_ == 0.0 || s >= static_cast<double>(last) * step_)
    return turn_.back() + rate_.back() * (s - static_cast<double>(last) * step_);
  const auto i = std::min(static_cast<std::size_t>(s / step_), last - 1);
  const double u = s / step_ - static_cast<double>(i), u2 = u * u, u3 = u2 * u;
  // The rotation vector's rate is the angular velocity to first order in the (small) turn.
  return (2.0 * u3 - 3.0 * u2 + 1.0) * turn_[i] + (u3 - 2.0 * u2 + u) * step_ * rate_[i] +
         (3.0 * u2 - 2.0 * u3) * turn_[i + 1] + (u3 - u2) * step_ * rate_[i + 1];
}

}  // namespace omnipose::pipeline
