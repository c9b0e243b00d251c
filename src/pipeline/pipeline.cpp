#include "omnipose/pipeline.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "common/problem_list.hpp"
#include "omnipose/motion_model.hpp"
#include "omnipose/so3.hpp"
#include "pipeline/frame_registrar.hpp"

namespace omnipose {
namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

/// Problems of the options other than the registration's, keyed by PipelineOptions field.
std::vector<std::string> otherProblems(const PipelineOptions& o) {
  std::vector<std::string> problems;
  for (const auto& p : o.unwrap.validate()) problems.push_back("unwrap." + p);
  for (const auto& p : o.fit.validate()) problems.push_back("fit." + p);
  detail::checkRange(problems, "refine_iterations", o.refine_iterations, 0, 5);
  detail::checkRange(problems, "threads", o.threads, 0, WindowRegistration::kMaxThreads,
                     " (0 = all online cores)");
  return problems;
}

}  // namespace

std::vector<std::string> PipelineOptions::validate() const {
  std::vector<std::string> problems;
  for (const auto& p : registration.validate()) problems.push_back("registration." + p);
  for (auto& p : otherProblems(*this)) problems.push_back(std::move(p));
  return problems;
}

std::vector<std::string> Pipeline::validate(const Calibration& calibration,
                                            const PipelineOptions& options) {
  std::vector<std::string> problems;
  const auto calibration_problems = calibration.validate();
  for (const auto& p : calibration_problems) problems.push_back("calibration: " + p);
  // The registration against the calibration's panorama (its size is only meaningful when
  // the calibration is valid).
  const auto registration_problems =
      calibration_problems.empty()
          ? WindowRegistration::validate(calibration.panorama.size(), options.registration)
          : options.registration.validate();
  for (const auto& p : registration_problems) problems.push_back("registration." + p);
  for (auto& p : otherProblems(options)) problems.push_back(std::move(p));
  return problems;
}

struct Pipeline::Impl {
  Impl(const Calibration& c, const PipelineOptions& o) : registrar(c, o, 0) {}
  pipeline::FrameRegistrar registrar;
};

Pipeline::Pipeline(const Calibration& calibration, const PipelineOptions& options) {
  detail::throwIfProblems("invalid pipeline configuration", validate(calibration, options));
  impl_ = std::make_unique<Impl>(calibration, options);
}

Pipeline::~Pipeline() = default;

void Pipeline::reset() { impl_->registrar.forgetPrevious(); }

Expected<FrameMotion> Pipeline::process(const cv::Mat& frame) {
  pipeline::FrameRegistrar& r = impl_->registrar;
  const auto t_start = Clock::now();
  const auto burst = r.frameBurst();
  FrameMotion result;

  // 1. Unwrap through the table built at start-up.
  if (auto ok = r.unwrap(frame); !ok) return std::unexpected(ok.error());
  result.timing.unwrap = secondsSince(t_start);

  // First frame of a sequence: its windows become the reference.
  if (!r.hasPrevious()) {
    const auto t_reg = Clock::now();
    r.makeCurrentPrevious();
    result.timing.registration = secondsSince(t_reg);
    result.timing.total = secondsSince(t_start);
    return result;
  }

  // 2. iFMI per window against the previous frame (its spectra are cached) and the robust
  // linear fit of the motion model.
  const auto t_reg = Clock::now();
  const std::optional<MotionEstimate> first = r.firstPass(&result.timing.fit);
  if (!first) return fail(ErrorCode::kInvalidArgument, "window registration rejected the panorama");
  result.timing.registration = secondsSince(t_reg) - result.timing.fit;

  // 3. Exact refinement against the same previous frame.
  const auto t_refine = Clock::now();
  const pipeline::PassResult refined =
      r.refine(*first, rotationFromVector(first->omega), first->tau,
               WindowRegistration::kPreviousFrame);
  result.timing.refine = secondsSince(t_refine);

  // The current frame's windows (unwarped) are the next reference.
  r.advance();

  result.has_motion = true;
  result.estimate = refined.estimate;
  result.rotation = refined.rotation;
  result.tau_norm = refined.estimate.tau.norm();
  result.translation_direction = result.tau_norm > 0
                                     ? Eigen::Vector3d(refined.estimate.tau / result.tau_norm)
                                     : Eigen::Vector3d::Zero();
  result.timing.total = secondsSince(t_start);
  return result;
}

std::span<const WindowMotion> Pipeline::lastWindows() const {
  return impl_->registrar.firstPassWindows();
}
const cv::Mat& Pipeline::lastPanorama() const { return impl_->registrar.panorama(); }
const Calibration& Pipeline::calibration() const { return impl_->registrar.calibration(); }
const PipelineOptions& Pipeline::options() const { return impl_->registrar.options(); }
int Pipeline::threads() const { return impl_->registrar.threads(); }
double Pipeline::windowAttenuation() const { return impl_->registrar.windowAttenuation(); }
bool Pipeline::wisdomLoaded() const { return impl_->registrar.wisdomLoaded(); }

}  // namespace omnipose
