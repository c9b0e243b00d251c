#include "pipeline/frame_rotation.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

#include "omnipose/so3.hpp"

namespace omnipose::pipeline {

namespace {

int piecesOver(double length) {
  return std::max(1, static_cast<int>(std::ceil(length / FrameRotation::kStepS)));
}

}  // namespace

FrameRotation::FrameRotation(double span_s, double max_exposure_s)
    : span_(std::abs(span_s)), max_exposure_(max_exposure_s) {
  const auto most = static_cast<std::size_t>(piecesOver(span_ + max_exposure_)) + 1;
  turn_.assign(most, Eigen::Vector3d::Zero());
  rate_ = turn_;
  layOut(0.0);
}

void FrameRotation::layOut(double exposure_s) {
  exposure_ = exposure_s;
  origin_ = -0.5 * exposure_s;
  const double length = span_ + exposure_s;
  const int pieces = piecesOver(length);
  step_ = length / pieces;
  count_ = std::min(static_cast<std::size_t>(pieces) + 1, turn_.size());
}

bool FrameRotation::measure(std::span<const GyroSample> samples, const ImuCalibration& imu,
                            const Eigen::Vector3d& bias, double time, double max_gap_s,
                            double exposure_s) {
  known_ = false;
  if (!(exposure_s >= 0.0 && exposure_s <= max_exposure_)) return false;
  layOut(exposure_s);
  Eigen::Matrix3d R = Eigen::Matrix3d::Identity();
  for (std::size_t i = 0; i < count_; ++i) {
    const double at = time + origin_ + static_cast<double>(i) * step_;
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
  if (origin_ < 0.0) {
    // The turns so far start at the exposure's beginning: re-referred to the timestamp,
    // where the curve through them stands at R0 (rates are in the axes of their own time).
    const Eigen::Matrix3d R0t = rotationFromVector(turnAt(0.0)).transpose();
    for (std::size_t i = 0; i < count_; ++i)
      turn_[i] = rotationVector(R0t * rotationFromVector(turn_[i]));
  }
  return true;
}

Eigen::Vector3d FrameRotation::turnAt(double s) const {
  const double x = s - origin_;
  const std::size_t last = count_ - 1;
  if (!(x > 0.0)) return turn_.front() + rate_.front() * x;
  if (step_ == 0.0 || x >= static_cast<double>(last) * step_)
    return turn_[last] + rate_[last] * (x - static_cast<double>(last) * step_);
  const auto i = std::min(static_cast<std::size_t>(x / step_), last - 1);
  const double u = x / step_ - static_cast<double>(i), u2 = u * u, u3 = u2 * u;
  // The rotation vector's rate is the angular velocity to first order in the (small) turn.
  return (2.0 * u3 - 3.0 * u2 + 1.0) * turn_[i] + (u3 - 2.0 * u2 + u) * step_ * rate_[i] +
         (3.0 * u2 - 2.0 * u3) * turn_[i + 1] + (u3 - u2) * step_ * rate_[i + 1];
}

Eigen::Vector3d FrameRotation::exposedTurnAt(double s) const {
  if (!(exposure_ > 0.0)) return turnAt(s);
  // turnAt() is one cubic between two kept samples and linear beyond them: two Gauss
  // points per stretch between sample times integrate it exactly.
  const double a = s - 0.5 * exposure_, b = s + 0.5 * exposure_;
  const double g = 0.5 / std::sqrt(3.0);
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  const double first = std::floor((a - origin_) / step_), end = std::ceil((b - origin_) / step_);
  for (double k = first; k < end; k += 1.0) {
    const double from = std::max(a, origin_ + k * step_);
    const double to = std::min(b, origin_ + (k + 1.0) * step_);
    const double mid = 0.5 * (from + to), length = to - from;
    if (length > 0.0) sum += 0.5 * length * (turnAt(mid - g * length) + turnAt(mid + g * length));
  }
  return sum / exposure_;
}

}  // namespace omnipose::pipeline
