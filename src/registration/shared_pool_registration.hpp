#pragma once
/// \file shared_pool_registration.hpp
/// Private to the library: a WindowRegistration that runs on a worker pool shared with the
/// pipeline's other stages instead of a pool of its own (FrameRegistrar). The public header
/// names no runtime type; this is the only way in.

#include <opencv2/core.hpp>

#include "omnipose/window_registration.hpp"
#include "runtime/fft_plan.hpp"
#include "runtime/worker_pool.hpp"

namespace omnipose {

class SharedPoolRegistration {
 public:
  /// As WindowRegistration(panorama, options, threads), but on `pool` (which must outlive the
  /// registration), planning FFTs with `effort` (kPatient when the plans are kept in a wisdom
  /// file). Throws std::invalid_argument listing every problem of
  /// WindowRegistration::validate(panorama, options).
  static WindowRegistration make(cv::Size panorama, const WindowRegistration::Options& options,
                                 runtime::WorkerPool& pool, runtime::PlanEffort effort);
};

}  // namespace omnipose
