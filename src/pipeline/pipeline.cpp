#include "omnipose/pipeline.hpp"

#include <algorithm>
#include <stdexcept>
#include <vector>

#include "omnipose/so3.hpp"
#include "pipeline/panorama_warp.hpp"
#include "registration/fft_plan.hpp"
#include "registration/worker_pool.hpp"

namespace omnipose {
namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

WindowRegistration::Options registrationOptions(const Calibration& calibration,
                                                const PipelineOptions& options) {
  WindowRegistration::Options o = options.registration;
  o.panorama_width = calibration.panorama.width;
  o.panorama_height = calibration.panorama.height;
  return o;
}

MotionFit::Options fitOptions(const Calibration& calibration, const PipelineOptions& options) {
  MotionFit::Options o = options.fit;
  const int step = std::max(options.registration.step, 1);
  o.max_windows = std::max(o.max_windows, (calibration.panorama.width + step - 1) / step);
  return o;
}

}  // namespace

std::vector<std::string> PipelineOptions::validate() const {
  std::vector<std::string> problems;
  if (auto bad = unwrap.validate(); !bad.empty()) problems.push_back("unwrap: " + bad);
  if (auto bad = registration.validate(); !bad.empty()) problems.push_back("registration: " + bad);
  if (auto bad = fit.validate(); !bad.empty()) problems.push_back("fit: " + bad);
  if (refine_iterations < 0 || refine_iterations > 5)
    problems.push_back("refine_iterations: must be in [0, 5]");
  if (threads < 0 || threads > 256)
    problems.push_back("threads: must be in [0, 256] (0 = all online cores)");
  return problems;
}

struct Pipeline::Impl {
  Impl(const Calibration& c, const PipelineOptions& o)
      : calibration(c),
        options(o),
        wisdom_loaded(registration::importWisdom(o.fftw_wisdom)),
        pool(o.threads > 0 ? o.threads : registration::WorkerPool::onlineCores()),
        unwrapper(c, o.unwrap),
        registration(registrationOptions(c, o), pool),
        fit(fitOptions(c, o), c.panorama.gamma(), o.registration.window),
        warp(c.panorama) {
    panorama = unwrapper.makePanorama();
    warped = unwrapper.makePanorama();
    // Mask, frame border, lens domain: what the windows must leave out.
    registration.setValidity(unwrapper.validity());
    windows.resize(registration.windowCount());
    refine_windows.resize(registration.windowCount());
    shifts_only.resize(registration.windowCount());  // rs_confidence 0: no rotation/scale
    // First start with a wisdom file configured: keep what FFTW_MEASURE chose (best effort:
    // an unwritable path only costs the determinism of the next start-up).
    if (!o.fftw_wisdom.empty() && !wisdom_loaded) (void)registration::exportWisdom(o.fftw_wisdom);
  }

  /// De-rotates `panorama` into `warped` on the pool, in bands of rows.
  void derotate(const Eigen::Matrix3d& R) {
    warp.prepare(panorama, R);
    const int rows = panorama.rows;
    const int bands = std::min(rows, 4 * pool.size());
    auto task = [&](int, int b) {
      warp.derotateRows(warped, b * rows / bands, (b + 1) * rows / bands);
    };
    pool.run(bands, task);
  }

  Calibration calibration;
  PipelineOptions options;
  bool wisdom_loaded;
  registration::WorkerPool pool;
  Unwrapper unwrapper;
  WindowRegistration registration;
  MotionFit fit;
  PanoramaWarp warp;
  cv::Mat panorama, warped;
  std::vector<WindowMotion> windows, refine_windows;
  std::vector<WindowMotion> shifts_only;  ///< "known" rotation/scale for a shift-only pass
  bool has_previous = false;
};

Pipeline::Pipeline(const Calibration& calibration, const PipelineOptions& options) {
  std::vector<std::string> problems = options.validate();
  for (const auto& p : calibration.validate()) problems.push_back("calibration: " + p);
  if (options.registration.window > calibration.panorama.height)
    problems.push_back("registration: window (" + std::to_string(options.registration.window) +
                       ") must not exceed the panorama height (" +
                       std::to_string(calibration.panorama.height) + ")");
  if (!problems.empty()) {
    std::string what = "invalid pipeline configuration:";
    for (const auto& p : problems) what += "\n  " + p;
    throw std::invalid_argument(what);
  }
  impl_ = std::make_unique<Impl>(calibration, options);
}

Pipeline::~Pipeline() = default;

void Pipeline::reset() { impl_->has_previous = false; }

Expected<FrameMotion> Pipeline::process(const cv::Mat& frame) {
  Impl& s = *impl_;
  const auto t_start = Clock::now();
  FrameMotion result;

  // 1. Unwrap through the table built at start-up.
  if (auto ok = s.unwrapper.unwrap(frame, s.panorama); !ok) return std::unexpected(ok.error());
  result.timing.unwrap = secondsSince(t_start);

  // First frame of a sequence: its windows become the reference.
  if (!s.has_previous) {
    const auto t_reg = Clock::now();
    s.registration.setReference(s.panorama);
    s.has_previous = true;
    result.timing.registration = secondsSince(t_reg);
    result.timing.total = secondsSince(t_start);
    return result;
  }

  // 2. iFMI per window against the previous frame (its spectra are cached).
  const auto t_reg = Clock::now();
  // With refinement to follow, the first pass only needs the shifts: the refinement pass
  // measures rotation and scale on the de-rotated panorama, where they are small.
  const bool shifts_only = s.options.refine_iterations > 0;
  if (!s.registration.measure(s.panorama, s.windows, true,
                              shifts_only ? std::span<const WindowMotion>(s.shifts_only)
                                          : std::span<const WindowMotion>()))
    return fail(ErrorCode::kInvalidArgument, "window registration rejected the panorama");
  result.timing.registration = secondsSince(t_reg);

  // 3. Robust linear fit of the motion model.
  const auto t_fit = Clock::now();
  const double u0 = s.calibration.panorama.forward_column;
  MotionEstimate est = s.fit.fit(s.windows, u0);
  result.timing.fit = secondsSince(t_fit);

  // 4. Exact refinement: de-rotate the current panorama by the estimate (exact cylinder
  // projection), fit what is left (residual rotation + translation), compose the rotation.
  const auto t_refine = Clock::now();
  Eigen::Matrix3d R = rotationFromVector(est.omega);
  Eigen::Vector3d tau = est.tau;
  for (int pass = 0; pass < s.options.refine_iterations && est.status != FitStatus::kLost;
       ++pass) {
    s.derotate(R);
    s.registration.measure(s.warped, s.refine_windows, false);
    const MotionEstimate residual = s.fit.fit(s.refine_windows, u0);
    if (residual.status == FitStatus::kLost) {
      est.status = FitStatus::kDegraded;  // keep the linear estimate, trust it less
      break;
    }
    R = rotationFromVector(residual.omega) * R;
    tau = residual.tau;
    est.covariance = residual.covariance;
    est.residual_rms_px = residual.residual_rms_px;
    est.windows_used = residual.windows_used;
    est.windows_masked = residual.windows_masked;
    est.iterations += residual.iterations;
    if (residual.status == FitStatus::kDegraded) est.status = FitStatus::kDegraded;
  }
  est.omega = rotationVector(R);
  est.tau = tau;
  result.timing.refine = secondsSince(t_refine);

  // The current frame's windows (unwarped) are the next reference.
  s.registration.advance();

  result.has_motion = true;
  result.estimate = est;
  result.rotation = R;
  result.tau_norm = tau.norm();
  result.translation_direction =
      result.tau_norm > 0 ? Eigen::Vector3d(tau / result.tau_norm) : Eigen::Vector3d::Zero();
  result.timing.total = secondsSince(t_start);
  return result;
}

std::span<const WindowMotion> Pipeline::lastWindows() const { return impl_->windows; }
const cv::Mat& Pipeline::lastPanorama() const { return impl_->panorama; }
const Calibration& Pipeline::calibration() const { return impl_->calibration; }
const PipelineOptions& Pipeline::options() const { return impl_->options; }
int Pipeline::threads() const { return impl_->pool.size(); }
bool Pipeline::wisdomLoaded() const { return impl_->wisdom_loaded; }

}  // namespace omnipose
