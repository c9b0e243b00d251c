#include "pipeline/frame_registrar.hpp"

#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>
#include <utility>

#include "omnipose/motion_model.hpp"
#include "omnipose/so3.hpp"
#include "registration/fft_plan.hpp"
#include "registration/pipeline_resources.hpp"

namespace omnipose::pipeline {
namespace {

/// The refinement pass's translation search is limited to a band of rows around the dv the
/// last fit predicts (WindowRegistration::measure(), expected_dv) when that prediction is
/// good to within the band: kPredictionSlackPx for the fit's error and the first-order
/// model, plus kDepthSpread times the predicted dv for the window's depth. Chosen from the
/// full-search dv of every window of the accuracy benchmark (docs/PERFORMANCE.md).
constexpr double kPredictionSlackPx = 4.0;
constexpr double kDepthSpread = 0.5;

/// The registration's options: each window's shift covariance is measured when the fit
/// uses it.
WindowRegistration::Options registrationOptions(const PipelineOptions& o) {
  WindowRegistration::Options r = o.registration;
  r.shift_covariance = r.shift_covariance || o.fit.window_covariance;
  return r;
}

}  // namespace

FrameRegistrar::WisdomFile::WisdomFile(std::string file)
    : path(std::move(file)),
      loaded(registration::importWisdom(path)),
      before(loaded ? registration::wisdomText() : std::string()) {}

registration::PlanEffort FrameRegistrar::WisdomFile::effort() const {
  // Plans that a file keeps are made once per machine: search them patiently. Without a
  // file every start-up plans again, so it measures only.
  return path.empty() ? registration::PlanEffort::kMeasure : registration::PlanEffort::kPatient;
}

void FrameRegistrar::WisdomFile::saveIfPlanned() const {
  if (!path.empty() && (!loaded || registration::wisdomText() != before))
    (void)registration::exportWisdom(path);
}

FrameRegistrar::FrameRegistrar(const Calibration& c, const PipelineOptions& o, int keyframe_slots)
    : calibration_(c),
      options_(o),
      wisdom_(o.fftw_wisdom),
      pool_(o.threads > 0 ? o.threads : registration::WorkerPool::onlineCores()),
      unwrapper_(c, o.unwrap),
      registration_(c.panorama.size(), registrationOptions(o),
                    WindowRegistration::PipelineResources{pool_, wisdom_.effort()}),
      fit_(o.fit, c.panorama.gamma(), o.registration.window, registration_.windowCount()),
      window_overlap_(windowOverlapFactor(o.registration.window, o.registration.step)),
      warp_(c.panorama) {
  panorama_ = unwrapper_.makePanorama();
  warped_ = unwrapper_.makePanorama();
  // Mask, frame border, lens domain: what the windows must leave out.
  registration_.setValidity(unwrapper_.validity());
  if (const int measurable = registration_.windowCount() - registration_.maskedWindowCount();
      measurable < MotionFit::kMinWindows) {
    throw std::invalid_argument(
        "the mask and the lens's domain leave " + std::to_string(measurable) + " of " +
        std::to_string(registration_.windowCount()) +
        " windows measurable; the fit needs at least " + std::to_string(MotionFit::kMinWindows) +
        " (omni.mask, registration.min_usable_fraction)");
  }
  registration_.reserveKeyframes(keyframe_slots);
  if (keyframe_slots > 0) ring_.emplace(c.panorama.size());
  for (int i = 0; i < keyframe_slots; ++i) keyframe_panoramas_.push_back(unwrapper_.makePanorama());
  const auto windows = static_cast<std::size_t>(registration_.windowCount());
  windows_.resize(windows);
  refine_windows_.resize(windows);
  shifts_only_.resize(windows);  // rs_confidence 0: no rotation/scale
  expected_dv_.resize(windows);
  wisdom_.saveIfPlanned();
}

Expected<void> FrameRegistrar::unwrap(const cv::Mat& frame) {
  const auto grey = unwrapper_.toGrey(frame);
  if (!grey) return std::unexpected(grey.error());
  const int rows = panorama_.rows, bands = std::min(rows, 4 * pool_.size());
  auto task = [&](int, int b) {
    unwrapper_.unwrapRows(**grey, panorama_, bandStart(b, bands, rows),
                          bandStart(b + 1, bands, rows));
  };
  pool_.run(bands, task);
  return {};
}

void FrameRegistrar::makeCurrentPrevious() {
  registration_.setReference(panorama_);
  has_previous_ = true;
}

std::optional<MotionEstimate> FrameRegistrar::firstPass(double* fit_seconds) {
  // With refinement to follow, the first pass only needs the shifts: the refinement pass
  // measures rotation and scale on the de-rotated panorama, where they are small.
  const bool shifts_only = options_.refine_iterations > 0;
  if (!has_previous_ ||
      !registration_.measure(panorama_, windows_, true,
                             shifts_only ? std::span<const WindowMotion>(shifts_only_)
                                         : std::span<const WindowMotion>()))
    return std::nullopt;
  const auto t_fit = std::chrono::steady_clock::now();
  MotionEstimate estimate = fitWindows(windows_);
  if (fit_seconds != nullptr)
    *fit_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t_fit).count();
  return estimate;
}

std::optional<MotionEstimate> FrameRegistrar::alignedPass(const Eigen::Matrix3d& R, int slot) {
  derotate(R);
  const bool shifts_only = options_.refine_iterations > 0;
  if (!registration_.measure(warped_, windows_, false,
                             shifts_only ? std::span<const WindowMotion>(shifts_only_)
                                         : std::span<const WindowMotion>(),
                             {}, slot))
    return std::nullopt;
  return fitWindows(windows_);
}

MotionEstimate FrameRegistrar::fitWindows(std::span<const WindowMotion> windows) {
  MotionEstimate estimate = fit_.fit(windows, calibration_.panorama.forward_column);
  estimate.covariance *= window_overlap_;
  return estimate;
}

PassResult FrameRegistrar::refine(const MotionEstimate& start, const Eigen::Matrix3d& R0,
                                  const Eigen::Vector3d& tau0, int against) {
  // De-rotate the current panorama by the estimate (exact cylinder projection), fit what is
  // left (residual rotation + translation), compose the rotation. The windows' rotation and
  // scale are searched again on the de-rotated panorama, their translation within a band
  // of rows around the dv the last fit predicts (predictRefinementShifts()).
  PassResult out;
  MotionEstimate est = start;
  Eigen::Matrix3d R = R0;
  Eigen::Vector3d tau = tau0;
  FitStatus last_fit = est.status;
  out.windows = windows_;
  out.window_model = start.vector();
  for (int pass = 0; pass < options_.refine_iterations && est.status != FitStatus::kLost; ++pass) {
    const Eigen::Matrix3d R_warp = wholeColumnYaw(R);
    derotate(R_warp);
    predictRefinementShifts(tau, last_fit);
    if (!registration_.measure(warped_, refine_windows_, false, {}, expected_dv_, against)) break;
    const MotionEstimate residual = fitWindows(refine_windows_);
    if (residual.status == FitStatus::kLost) {
      est.status = FitStatus::kDegraded;  // keep the estimate so far, trust it less
      break;
    }
    R = rotationFromVector(residual.omega) * R_warp;
    tau = residual.tau;
    last_fit = residual.status;
    est.covariance = residual.covariance;
    est.residual_rms_px = residual.residual_rms_px;
    est.windows_used = residual.windows_used;
    est.windows_masked = residual.windows_masked;
    est.iterations += residual.iterations;
    if (residual.status == FitStatus::kDegraded) est.status = FitStatus::kDegraded;
    out.refined = true;
    out.windows = refine_windows_;
    out.window_model = residual.vector();
  }
  est.omega = rotationVector(R);
  est.tau = tau;
  out.estimate = est;
  out.rotation = R;
  return out;
}

bool FrameRegistrar::storeKeyframe(int slot) {
  if (!has_previous_ || !registration_.storeKeyframe(slot)) return false;
  std::swap(panorama_, keyframe_panoramas_[static_cast<std::size_t>(slot)]);  // headers only
  return true;
}

std::optional<double> FrameRegistrar::ringYaw(int slot, double min_peak) {
  if (!ring_ || !registration_.hasKeyframe(slot)) return std::nullopt;
  const RingAlignment::Shift shift =
      ring_->align(keyframe_panoramas_[static_cast<std::size_t>(slot)], panorama_);
  if (!(shift.peak >= min_peak)) return std::nullopt;
  // A yaw moves every column by the same angle; the model's sign convention gives the
  // direction (DESIGN.md section 3).
  Eigen::Matrix<double, 6, 1> unit_yaw;
  unit_yaw << 0.0, 0.0, 1.0, 0.0, 0.0, 0.0;
  const double du_per_rad = predictMotion(unit_yaw, 0.0, fit_.kappa()).du_rad;
  return shift.du_px * calibration_.panorama.gamma() / (du_per_rad < 0.0 ? -1.0 : 1.0);
}

Eigen::Matrix3d FrameRegistrar::wholeColumnYaw(const Eigen::Matrix3d& R) const {
  // The warp's interpolation kernel moves content by a fraction of a pixel slightly wrong
  // (about +-0.005 px, depending on the fraction), which the residual pass reads as yaw; the
  // same fraction every frame (a steady turn) adds up. A whole-column yaw is resampled
  // exactly; the residual fit measures the remaining fraction (docs/results/ANALYSIS.md).
  // Only where the de-rotation is nearly a column shift: with a tilt of more than a pixel
  // every sample is interpolated anyway, and rounding would only add to the residual.
  const double gamma = calibration_.panorama.gamma();
  if (std::acos(std::clamp(R(2, 2), -1.0, 1.0)) > gamma) return R;
  const double yaw = std::atan2(R(1, 0), R(0, 0));
  const double rounded = std::round(yaw / gamma) * gamma;
  return Eigen::AngleAxisd(rounded - yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() * R;
}

void FrameRegistrar::predictRefinementShifts(const Eigen::Vector3d& tau, FitStatus last_fit) {
  if (last_fit != FitStatus::kOk) {
    std::fill(expected_dv_.begin(), expected_dv_.end(), std::numeric_limits<double>::quiet_NaN());
    return;
  }
  const double gamma = calibration_.panorama.gamma();
  for (int k = 0; k < registration_.windowCount(); ++k) {
    Eigen::Matrix<double, 6, 1> x;
    x << Eigen::Vector3d::Zero(), fit_.inverseDepth(k) * tau;
    const double theta = calibration_.panorama.azimuth(registration_.windowCenter(k));
    const double dv = predictMotion(x, theta, fit_.kappa()).dv_rad / gamma;
    const bool tight = kPredictionSlackPx + kDepthSpread * std::abs(dv) <=
                       WindowRegistration::kExpectedDvReachPx;
    expected_dv_[k] = tight ? dv : std::numeric_limits<double>::quiet_NaN();
  }
}

void FrameRegistrar::derotate(const Eigen::Matrix3d& R) {
  // The projection grid in bands of grid rows (and the padded copy as one more task), then
  // the image in bands of rows.
  const int grid_rows = warp_.gridRows(), grid_bands = std::min(grid_rows, 2 * pool_.size());
  auto prepare = [&](int, int b) {
    if (b == grid_bands) {
      warp_.padCurrent(panorama_);
    } else {
      warp_.projectGridRows(R, bandStart(b, grid_bands, grid_rows),
                            bandStart(b + 1, grid_bands, grid_rows));
    }
  };
  pool_.run(grid_bands + 1, prepare);
  const int rows = panorama_.rows, bands = std::min(rows, 4 * pool_.size());
  auto task = [&](int, int b) {
    warp_.derotateRows(warped_, bandStart(b, bands, rows), bandStart(b + 1, bands, rows));
  };
  pool_.run(bands, task);
}

}  // namespace omnipose::pipeline
