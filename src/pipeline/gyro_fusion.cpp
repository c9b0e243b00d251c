#include "pipeline/gyro_fusion.hpp"

#include <Eigen/Cholesky>
#include <cmath>
#include <limits>

#include "omnipose/so3.hpp"

namespace omnipose::pipeline {

double gyroRotationVariance(double noise_density, double bias_sigma, double dt) {
  if (!std::isfinite(noise_density) || !std::isfinite(bias_sigma) || !std::isfinite(dt))
    return std::numeric_limits<double>::infinity();
  return noise_density * noise_density * std::abs(dt) + bias_sigma * bias_sigma * dt * dt;
}

bool fuseGyroRotation(Eigen::Matrix3d& rotation, MotionEstimate& estimate,
                      const Eigen::Matrix3d& gyro, double gyro_variance) {
  using Mat6 = Eigen::Matrix<double, 6, 6>;
  if (!(gyro_variance > 0.0) || !std::isfinite(gyro_variance)) return false;
  const Mat6& C = estimate.covariance;
  if (!C.allFinite()) return false;
  Eigen::Matrix3d S = C.topLeftCorner<3, 3>();
  S.diagonal().array() += gyro_variance;
  const Eigen::LLT<Eigen::Matrix3d> llt(S);
  if (llt.info() != Eigen::Success || !(C.topLeftCorner<3, 3>().diagonal().minCoeff() > 0.0))
    return false;
  const Eigen::Matrix<double, 6, 3> CS = C.leftCols<3>();
  // K^T = S^-1 C[omega, :] (S and C symmetric).
  const Eigen::Matrix<double, 3, 6> Kt = llt.solve(CS.transpose());
  const Eigen::Vector3d innovation = rotationVector(rotation.transpose() * gyro);
  const Eigen::Matrix<double, 6, 1> dx = Kt.transpose() * innovation;
  if (!dx.allFinite()) return false;
  rotation = rotation * rotationFromVector(dx.head<3>());
  estimate.omega = rotationVector(rotation);
  estimate.tau += dx.tail<3>();
  Mat6 updated = C - Kt.transpose() * CS.transpose();
  estimate.covariance = 0.5 * (updated + updated.transpose());
  return true;
}

}  // namespace omnipose::pipeline
