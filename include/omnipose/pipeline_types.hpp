#pragma once
/// \file pipeline_types.hpp
/// What one frame-to-frame motion estimate carries, shared by every method.

#include <Eigen/Core>

#include "omnipose/motion_fit.hpp"

namespace omnipose {

/// Wall time of each stage of one process() call, seconds.
struct StageTiming {
  double unwrap = 0.0;
  double registration = 0.0;
  double fit = 0.0;
  double refine = 0.0;  ///< warp + re-registration + fit of the refinement passes
  double total = 0.0;
};

/// Motion of the current frame relative to the previous one.
struct FrameMotion {
  bool has_motion = false;  ///< false for the first frame after start/reset (no pair yet)
  MotionEstimate estimate;  ///< omega and tau after refinement; covariance of the last pass,
                            ///< times windowOverlapFactor() (window_motion.hpp)
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  ///< R = exp([omega]x)
  Eigen::Vector3d translation_direction = Eigen::Vector3d::Zero();  ///< t/|t|, 0 if |tau|=0
  double tau_norm = 0.0;    ///< |tau| = |t| / rho
  StageTiming timing;
};

}  // namespace omnipose
