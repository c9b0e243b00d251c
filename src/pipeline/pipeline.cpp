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
#include "pipeline/panorama_warp.hpp"
#include "registration/fft_plan.hpp"
#include "registration/worker_pool.hpp"

namespace omnipose {
namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

/// The refinement pass's translation search is limited to a band of rows around the dv the
/// last fit predicts (WindowRegistration::measure(), expected_dv) when that prediction is
/// good to within the band: kPredictionSlackPx for the fit's error and the first-order
/// model, plus kDepthSpread times the predicted dv for the window's depth. Measured on the
/// accuracy benchmark's 18 sequences (every window valid in the refinement pass, 22,600
/// windows): |full-search dv - predicted dv| p99 0.02-1.09 px, at most 1.6 px except
/// 1 window each of the kogeto sequences (5.6, 7.6 px) and the mast's windows in the unmasked
/// sequence (up to 17 px: the mast does not move with the scene; those windows are
/// outliers either way).
constexpr double kPredictionSlackPx = 4.0;
constexpr double kDepthSpread = 0.5;

/// Problems of the options other than the registration's, keyed by PipelineOptions field.
std::vector<std::string> otherProblems(const PipelineOptions& o) {
  std::vector<std::string> problems;
  for (const auto& p : o.unwrap.validate()) problems.push_back("unwrap." + p);
  for (const auto& p : o.fit.validate()) problems.push_back("fit." + p);
  detail::checkRange(problems, "refine_iterations", o.refine_iterations, 0, 5);
  detail::checkRange(problems, "threads", o.threads, 0, 256, " (0 = all online cores)");
  return problems;
}

cv::Size panoramaSize(const Calibration& calibration) {
  return {calibration.panorama.width, calibration.panorama.height};
}

/// The FFTW wisdom file of PipelineOptions::fftw_wisdom ("" = none), loaded before any
/// plan is made.
struct WisdomFile {
  explicit WisdomFile(std::string file)
      : path(std::move(file)),
        loaded(registration::importWisdom(path)),
        before(loaded ? registration::wisdomText() : std::string()) {}

  /// Plans that a file keeps are made once per machine: search them patiently. Without a
  /// file every start-up plans again, so it measures only.
  registration::PlanEffort effort() const {
    return path.empty() ? registration::PlanEffort::kMeasure : registration::PlanEffort::kPatient;
  }

  /// Writes the file when it was not read (first start) or planning added to the wisdom
  /// (a file from other transform sizes or an older omnipose). Best effort: an unwritable
  /// path only costs the determinism of the next start-up.
  void saveIfPlanned() const {
    if (!path.empty() && (!loaded || registration::wisdomText() != before))
      (void)registration::exportWisdom(path);
  }

  std::string path;
  bool loaded;         ///< the file was read
  std::string before;  ///< the process's wisdom after reading the file (when it was read)
};

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
          ? WindowRegistration::validate(panoramaSize(calibration), options.registration)
          : options.registration.validate();
  for (const auto& p : registration_problems) problems.push_back("registration." + p);
  for (auto& p : otherProblems(options)) problems.push_back(std::move(p));
  return problems;
}

struct Pipeline::Impl {
  Impl(const Calibration& c, const PipelineOptions& o)
      : calibration(c),
        options(o),
        wisdom(o.fftw_wisdom),
        pool(o.threads > 0 ? o.threads : registration::WorkerPool::onlineCores()),
        unwrapper(c, o.unwrap),
        registration(panoramaSize(c), o.registration, pool, wisdom.effort()),
        fit(o.fit, c.panorama.gamma(), o.registration.window, registration.windowCount()),
        warp(c.panorama) {
    panorama = unwrapper.makePanorama();
    warped = unwrapper.makePanorama();
    // Mask, frame border, lens domain: what the windows must leave out.
    registration.setValidity(unwrapper.validity());
    if (const int measurable = registration.windowCount() - registration.maskedWindowCount();
        measurable < MotionFit::kMinWindows) {
      throw std::invalid_argument(
          "the mask and the lens's domain leave " + std::to_string(measurable) + " of " +
          std::to_string(registration.windowCount()) + " windows measurable; the fit needs at least " +
          std::to_string(MotionFit::kMinWindows) + " (omni.mask, registration.min_usable_fraction)");
    }
    windows.resize(registration.windowCount());
    refine_windows.resize(registration.windowCount());
    shifts_only.resize(registration.windowCount());  // rs_confidence 0: no rotation/scale
    expected_dv.resize(registration.windowCount());
    wisdom.saveIfPlanned();
  }

  /// Rows [0, rows) split into `bands` ranges: the first row of band b.
  static int bandStart(int b, int bands, int rows) { return b * rows / bands; }

  /// Unwraps `frame` into `panorama`, the lookup in bands of rows on the pool.
  Expected<void> unwrap(const cv::Mat& frame) {
    const auto grey = unwrapper.toGrey(frame);
    if (!grey) return std::unexpected(grey.error());
    const int rows = panorama.rows, bands = std::min(rows, 4 * pool.size());
    auto task = [&](int, int b) {
      unwrapper.unwrapRows(**grey, panorama, bandStart(b, bands, rows),
                           bandStart(b + 1, bands, rows));
    };
    pool.run(bands, task);
    return {};
  }

  /// expected_dv for a refinement pass after a fit that gave `tau` (fit holds its inverse
  /// depths): the translation part of the model per window (the rotation is what the
  /// de-rotation removed), NaN where the band search would not cover its uncertainty, and
  /// everywhere after a fit that was not kOk (few windows or a large residual).
  void predictRefinementShifts(const Eigen::Vector3d& tau, FitStatus last_fit) {
    if (last_fit != FitStatus::kOk) {
      std::fill(expected_dv.begin(), expected_dv.end(), std::numeric_limits<double>::quiet_NaN());
      return;
    }
    const double gamma = calibration.panorama.gamma();
    for (int k = 0; k < registration.windowCount(); ++k) {
      Eigen::Matrix<double, 6, 1> x;
      x << Eigen::Vector3d::Zero(), fit.inverseDepth(k) * tau;
      const double theta = calibration.panorama.azimuth(registration.windowCenter(k));
      const double dv = predictMotion(x, theta, fit.kappa()).dv_rad / gamma;
      const bool tight = kPredictionSlackPx + kDepthSpread * std::abs(dv) <=
                         WindowRegistration::kExpectedDvReachPx;
      expected_dv[k] = tight ? dv : std::numeric_limits<double>::quiet_NaN();
    }
  }

  /// De-rotates `panorama` into `warped` on the pool: the projection grid in bands of grid
  /// rows (and the padded copy as one more task), then the image in bands of rows.
  void derotate(const Eigen::Matrix3d& R) {
    const int grid_rows = warp.gridRows(), grid_bands = std::min(grid_rows, 2 * pool.size());
    auto prepare = [&](int, int b) {
      if (b == grid_bands) {
        warp.padCurrent(panorama);
      } else {
        warp.projectGridRows(R, bandStart(b, grid_bands, grid_rows),
                             bandStart(b + 1, grid_bands, grid_rows));
      }
    };
    pool.run(grid_bands + 1, prepare);
    const int rows = panorama.rows, bands = std::min(rows, 4 * pool.size());
    auto task = [&](int, int b) {
      warp.derotateRows(warped, bandStart(b, bands, rows), bandStart(b + 1, bands, rows));
    };
    pool.run(bands, task);
  }

  Calibration calibration;
  PipelineOptions options;
  WisdomFile wisdom;
  registration::WorkerPool pool;
  Unwrapper unwrapper;
  WindowRegistration registration;
  MotionFit fit;
  PanoramaWarp warp;
  cv::Mat panorama, warped;
  std::vector<WindowMotion> windows, refine_windows;
  std::vector<WindowMotion> shifts_only;  ///< "known" rotation/scale for a shift-only pass
  std::vector<double> expected_dv;        ///< refinement pass: dv per window, or NaN
  bool has_previous = false;
};

Pipeline::Pipeline(const Calibration& calibration, const PipelineOptions& options) {
  detail::throwIfProblems("invalid pipeline configuration", validate(calibration, options));
  impl_ = std::make_unique<Impl>(calibration, options);
}

Pipeline::~Pipeline() = default;

void Pipeline::reset() { impl_->has_previous = false; }

Expected<FrameMotion> Pipeline::process(const cv::Mat& frame) {
  Impl& s = *impl_;
  const auto t_start = Clock::now();
  FrameMotion result;

  // 1. Unwrap through the table built at start-up.
  if (auto ok = s.unwrap(frame); !ok) return std::unexpected(ok.error());
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

  // The first pass keeps the per-window depth even when a refinement follows: a uniform
  // depth there made the refined estimates worse (docs/PERFORMANCE.md).

  // 4. Exact refinement: de-rotate the current panorama by the estimate (exact cylinder
  // projection), fit what is left (residual rotation + translation), compose the rotation.
  // The windows' rotation/scale are searched again on the de-rotated panorama: predicting
  // them from the first pass instead is off by ~1 mrad and ~0.2 % in scale, too much for
  // the accuracy (docs/PERFORMANCE.md). The windows' translation peaks are searched within
  // a band of rows around the dv the last fit predicts (predictRefinementShifts()); windows
  // that do not move with the scene (a robot's mast) then rarely lock onto it.
  const auto t_refine = Clock::now();
  Eigen::Matrix3d R = rotationFromVector(est.omega);
  Eigen::Vector3d tau = est.tau;
  FitStatus last_fit = est.status;
  for (int pass = 0; pass < s.options.refine_iterations && est.status != FitStatus::kLost;
       ++pass) {
    s.derotate(R);
    s.predictRefinementShifts(tau, last_fit);
    s.registration.measure(s.warped, s.refine_windows, false, {}, s.expected_dv);
    const MotionEstimate residual = s.fit.fit(s.refine_windows, u0);
    if (residual.status == FitStatus::kLost) {
      est.status = FitStatus::kDegraded;  // keep the linear estimate, trust it less
      break;
    }
    R = rotationFromVector(residual.omega) * R;
    tau = residual.tau;
    last_fit = residual.status;
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
double Pipeline::windowAttenuation() const { return impl_->fit.kappa(); }
bool Pipeline::wisdomLoaded() const { return impl_->wisdom.loaded; }

}  // namespace omnipose
