#pragma once
/// \file pipeline.hpp
/// The per-frame pipeline of DESIGN.md section 1 behind one entry point: unwrap ->
/// sliding-window iFMI against the previous frame -> robust linear fit -> exact
/// refinement -> relative pose (R, t up to scale).
///
/// Exact refinement: the first-order model is exact only for small rotations, and each
/// window reports the motion averaged over 36 degrees of azimuth. After the linear fit the
/// current panorama is de-rotated by the estimated R with the exact cylinder projection,
/// re-registered against the same previous windows, and the residual motion is fitted:
/// R <- R_res R, and tau is the residual fit's translation (de-rotation does not move the
/// camera centre). The residual rotation is small, so its first-order error is negligible;
/// translation stays first order (it is small per frame), with per-window inverse depth.
/// The re-registration searches each window's translation within
/// WindowRegistration::kExpectedDvReachPx of the dv the last fit predicts for it (the
/// translation part of its model; every shift when that prediction is looser, or the fit
/// was not kOk): a cut-off peak leaves the window out instead of giving a wrong shift.
///
/// Realtime: the constructor allocates everything (the worker threads included); process()
/// allocates nothing and never throws. Not thread-safe: one caller at a time.

#include <Eigen/Core>
#include <chrono>
#include <memory>
#include <opencv2/core.hpp>
#include <span>
#include <string>

#include "omnipose/calibration.hpp"
#include "omnipose/error.hpp"
#include "omnipose/motion_estimator.hpp"
#include "omnipose/motion_fit.hpp"
#include "omnipose/unwrapper.hpp"
#include "omnipose/window_registration.hpp"

namespace omnipose {

struct PipelineOptions {
  Unwrapper::Options unwrap;
  /// Window size/step and iFMI settings; the panorama size is the calibration's.
  WindowRegistration::Options registration;
  MotionFit::Options fit;
  /// Warp-and-refit passes after the linear fit (0 = plain first-order fit).
  int refine_iterations = 1;
  /// The refinement pass checks each window's pixels against the window's own motion and
  /// lowers the confidence of windows that content moving on its own (people walking by)
  /// covers in part: fully weighted up to 1 % of the window's taper weight disagreeing, left
  /// out from 6 % (src/pipeline/moving_content.hpp; DESIGN.md section 4). Costs about 3 %
  /// of a frame's instructions; without refinement (refine_iterations 0) it does nothing.
  bool moving_content = true;
  /// In the refinement pass each window is de-rotated/de-scaled, before its shift is measured,
  /// by the rotation and scale the last fit predicts for it (the rotation left after the
  /// de-rotation, the translation at the window's inverse depth: smooth around the ring)
  /// instead of by its own measured ones (noisy: at 0.1 px of corner motion the noise alone
  /// decides whether a window is re-sampled). Not when the first pass's translation is within
  /// what the pair's tilt a can make its first-order fit read (10 a^2, radians). The windows'
  /// measured rotation and scale still go to the fit. Off by default (docs/results/ANALYSIS.md,
  /// "De-warping by the fit's prediction").
  bool dewarp_by_fit = false;
  /// With a rolling shutter (or an exposure) and the robot's gyro: measure, against the gyro,
  /// how much earlier or later than the model's capture times the windows' yaw was read (their
  /// texture sets it) and read it there (src/pipeline/capture_time_offset.hpp; DESIGN.md
  /// section 3, "Rolling shutter with a gyro"). Without a gyro it does nothing. A camera-gyro
  /// clock offset that is off by more than the texture's offset (0.05-0.15 ms) makes it follow
  /// the clock's error instead: `omnipose-calibrate --imu-from` measures the clock without it.
  bool yaw_capture_time = true;
  /// With the robot's gyro: each pair's motion (and each keyframe registration's) is the
  /// images' combined with the gyro's rotation over the same interval, each weighed by its
  /// covariance (the fit's; the gyro's white noise, calibration.yaml `imu.gyro_noise_density`,
  /// and the uncertainty of its bias as the images track it), the translation corrected
  /// through its correlation with the rotation (src/pipeline/gyro_fusion.hpp; DESIGN.md
  /// section 3, "The gyro in each pair"). People walking by bend the images' rotation, not
  /// the gyro's. The gyro's bias is still read from the images' rotation alone. Without a
  /// gyro, or where its samples do not cover the pair, it does nothing.
  bool gyro_fusion = true;
  /// Worker threads for the window registration and the de-rotation, the processing thread
  /// included, created at start-up (1 = everything on the calling thread; 0 = all online
  /// cores; at most WindowRegistration::kMaxThreads). The result is bit-identical for any
  /// value.
  /// A library starts no threads unless asked: the default is 1 (omniposed and
  /// omnipose-replay default to 0). Idle workers spin up to 50 us after each job, then block.
  int threads = 1;
  /// FFTW wisdom file ("" = none): loaded before the FFT plans are made, so every start-up
  /// uses the same FFT algorithms (deterministic speed and results). Plans it lacks (first
  /// start: the file does not exist yet) are searched with FFTW_PATIENT (about 0.5 s once,
  /// ~6 % faster per frame than FFTW_MEASURE, which is used without a file) and the file is
  /// written. An unwritable path is not an error: the next start-up plans again.
  std::string fftw_wisdom;

  /// Every problem of the options alone, one message per bad field, each starting with the
  /// field's path in this struct ("registration.window: 8 is outside [16, 512] pixels",
  /// "fit.median: ...", "threads: ..."); empty when valid.
  std::vector<std::string> validate() const;
};

class Pipeline final : public MotionEstimator {
 public:
  /// Every problem that would stop the constructor, without building anything: the
  /// calibration's ("calibration: ..."), the options' (as PipelineOptions::validate()) and
  /// the registration against the calibration's panorama ("registration.window: 200 is
  /// larger than the panorama (1100 x 110)", too many window samples). Empty when valid.
  static std::vector<std::string> validate(const Calibration& calibration,
                                           const PipelineOptions& options);

  /// Throws std::invalid_argument listing every problem of validate(calibration, options),
  /// or saying how many windows are left when the mask and the lens's domain leave fewer
  /// than MotionFit::kMinWindows measurable (every frame would be lost).
  Pipeline(const Calibration& calibration, const PipelineOptions& options);
  ~Pipeline();
  Pipeline(const Pipeline&) = delete;
  Pipeline& operator=(const Pipeline&) = delete;

  /// Processes the next frame (8-bit grey/BGR/BGRA, omni or panorama per the options).
  /// A rejected frame (kBadFrame: wrong size/type, black) leaves the state untouched, so
  /// the next good frame is compared with the last good one.
  Expected<FrameMotion> process(const cv::Mat& frame) override;
  /// Forgets the previous frame: the next frame starts a new pair sequence.
  void reset() override;
  const char* name() const override { return "ifmi"; }

  /// Window motions of the last pair, first (linear) pass: for diagnostics and plots.
  std::span<const WindowMotion> lastWindows() const;
  /// The last unwrapped panorama (CV_32FC1).
  const cv::Mat& lastPanorama() const;
  const Calibration& calibration() const;
  const PipelineOptions& options() const;
  /// The window attenuation kappa of the motion model (motion_model.hpp), as the fit uses it.
  double windowAttenuation() const;
  /// Worker threads in use (PipelineOptions::threads resolved; the calling thread included).
  int threads() const;
  /// Whether options().fftw_wisdom was read (true), or is missing/unreadable (false).
  bool wisdomLoaded() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace omnipose
