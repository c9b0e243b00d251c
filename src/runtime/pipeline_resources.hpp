#pragma once
/// \file pipeline_resources.hpp
/// The definition of WindowRegistration::PipelineResources (private): the public header only
/// declares it, so that only the library (the pipeline's FrameRegistrar) can reach the
/// constructor that takes it, and the public header names none of these private types.

#include "omnipose/window_registration.hpp"
#include "runtime/fft_plan.hpp"
#include "runtime/worker_pool.hpp"

namespace omnipose {

struct WindowRegistration::PipelineResources {
  /// The workers the registration runs on (shared with the pipeline's other stages); must
  /// outlive the registration.
  runtime::WorkerPool& pool;
  /// How long FFTW plans (kPatient when the plans are kept in a wisdom file).
  runtime::PlanEffort effort;
};

}  // namespace omnipose
