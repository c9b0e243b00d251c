#pragma once
/// \file motion_estimator.hpp
/// The interface every frame-to-frame motion method implements (the iFMI pipeline and
/// the feature-based baselines), so replay, evaluation and the daemon treat them alike.

#include <opencv2/core.hpp>

#include "omnipose/error.hpp"
#include "omnipose/pipeline_types.hpp"

namespace omnipose {

class MotionEstimator {
 public:
  virtual ~MotionEstimator() = default;
  /// Motion of `frame` relative to the previous good frame (see Pipeline::process).
  virtual Expected<FrameMotion> process(const cv::Mat& frame) = 0;
  /// Forgets the previous frame.
  virtual void reset() = 0;
  /// Short method name ("ifmi", "orb5pt", ...).
  virtual const char* name() const = 0;
};

}  // namespace omnipose
