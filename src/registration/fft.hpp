#pragma once
/// \file fft.hpp
/// The FFT types of the runtime layer under the names the registration stages use (private).

#include "runtime/fft_plan.hpp"

namespace omnipose::registration {

using runtime::Complex;
using runtime::FftPlan;
using runtime::FftwArray;
using runtime::PlanEffort;

}  // namespace omnipose::registration
