#pragma once
/// \file frame_registrar.hpp
/// The registration machinery of one frame (private to the core library), shared by
/// Pipeline (frame pairs) and Odometry (keyframes): the unwrap, the shift-only first pass
/// against the previous frame, the warp-and-refit refinement against the previous frame or
/// a keyframe, keyframe slots and the whole-ring yaw search. Pipeline::process() and
/// Odometry::process() are the two ways these steps are composed.
///
/// Realtime: the constructor allocates everything (the worker threads included); nothing
/// else allocates or throws. Not thread-safe.

#include <Eigen/Core>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/error.hpp"
#include "omnipose/gyro.hpp"
#include "omnipose/motion_fit.hpp"
#include "omnipose/pipeline.hpp"
#include "omnipose/unwrapper.hpp"
#include "omnipose/window_registration.hpp"
#include "pipeline/frame_rotation.hpp"
#include "pipeline/moving_content.hpp"
#include "pipeline/panorama_warp.hpp"
#include "pipeline/ring_alignment.hpp"
#include "pipeline/vertical_scale.hpp"
#include "runtime/worker_pool.hpp"

namespace omnipose::pipeline {

/// What a sequence of fit passes produced.
struct PassResult {
  /// omega and tau of the whole estimate (first pass and refinements composed); status,
  /// covariance, residual and windows_used of the last pass that succeeded.
  MotionEstimate estimate;
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();  ///< exp([estimate.omega]x)
  bool refined = false;  ///< at least one refinement pass succeeded
  /// The windows of the pass that made the estimate and the motion that pass fitted to
  /// them (relative to the panorama it registered: a residual after a de-rotation).
  std::span<const WindowMotion> windows;
  /// How much each of `windows` weighed in that pass's fit (MotionFit::finalWeight()).
  std::span<const double> window_weights;
  Eigen::Matrix<double, 6, 1> window_model = Eigen::Matrix<double, 6, 1>::Zero();
  /// The windows' rows were moved to the frames' timestamps with the gyro (the rotation of
  /// every row within its frame known): the motion is between the timestamps, yaw included.
  bool gyro_rows = false;
};

/// What a pass needs to read each window's motion, measured between rows captured at
/// different times (Calibration::sensor, a rolling shutter), as the motion between the two
/// frames' timestamps, yaw excepted: that is read between the windows' mean capture times
/// (meanWindowTime(); ReadoutYaw moves it to the timestamps; DESIGN.md section 3, "Rolling
/// shutter").
struct ShutterContext {
  double interval_s = 0.0;  ///< t_current - t_reference, seconds; <= 0: no correction
  /// The previous pair's motion as its fit gave it (omega, its yaw between the windows' mean
  /// capture times; tau) divided by its interval (per second), and that interval;
  /// previous_interval_s <= 0: unknown (the velocity is taken as constant).
  Eigen::Matrix<double, 6, 1> previous_velocity = Eigen::Matrix<double, 6, 1>::Zero();
  double previous_interval_s = 0.0;
  /// The gyro's rotation from the reference's timestamp to the current frame's
  /// (integrateGyro()), when known: the first pass's estimate of the rotation that the rows'
  /// own rotations (FrameRegistrar::measureRowRotations()) are carried through.
  std::optional<Eigen::Matrix3d> gyro_rotation;
};


class FrameRegistrar {
 public:
  /// Throws std::invalid_argument as Pipeline's constructor. `keyframe_slots` in [0, 16].
  FrameRegistrar(const Calibration& calibration, const PipelineOptions& options,
                 int keyframe_slots);

  /// Keeps the workers awake between the jobs of one frame (WorkerPool::Burst): held by
  /// the caller for the whole of one frame's processing.
  [[nodiscard]] runtime::WorkerPool::Burst frameBurst() {
    return runtime::WorkerPool::Burst(pool_);
  }

  /// Unwraps `frame` into the current panorama (kBadFrame / kInvalidArgument on a frame of
  /// the wrong size or type, or black).
  Expected<void> unwrap(const cv::Mat& frame);

  /// The row timing of the next passes (until set again). Without a readout time in the
  /// calibration it changes nothing.
  void setShutter(const ShutterContext& shutter) { shutter_ = shutter; }

  /// The camera's rotation within the current frame (timestamp `time`, camera seconds,
  /// exposed for `exposure_s` seconds in [0, SensorTiming::kMaxExposureS]: its own or the
  /// calibration's) from the gyro's `samples` (FrameRotation): passes against a reference
  /// whose rotation is known too then take each window's capture times out exactly
  /// (DESIGN.md section 3, "Rolling shutter with a gyro") instead of from the pair's own
  /// motion. False (unknown: the images alone) when the samples do not cover the frame's
  /// readout and exposure, and for a global shutter without an exposure (nothing to take
  /// out). With an exposure it gives the registration each window's blur path too
  /// (passMotionBlur()), or takes it back.
  bool measureRowRotations(std::span<const GyroSample> samples, const ImuCalibration& imu,
                           const Eigen::Vector3d& bias, double time, double max_gap_s,
                           double exposure_s);

  /// The current frame's rows' rotations unknown (the images alone), its blur path cleared.
  void forgetRowRotations();

  /// Whether the rows' poses differ from the timestamp's: a rolling shutter, or a frame
  /// exposed for `exposure_s` > 0 seconds (motion blur). Only then do the rows need the gyro.
  bool rowsMoveWithinFrame(double exposure_s) const {
    return calibration_.sensor.readout_s != 0.0 || exposure_s > 0.0;
  }

  /// With the gyro's rows (measureRowRotations()), every window's yaw within its frame is read
  /// `offset_s` seconds after its modelled capture time (CaptureTimeOffset: where its texture
  /// puts it); roll and pitch are not moved. 0, the default, reads them at the model's.
  void setYawTimeOffset(double offset_s) { yaw_time_offset_ = offset_s; }

  /// Whether a previous frame is set (the first pass can run).
  bool hasPrevious() const { return has_previous_; }
  /// The current panorama becomes the previous frame (its spectra computed anew).
  void makeCurrentPrevious();
  /// Forgets the previous frame.
  void forgetPrevious() {
    has_previous_ = false;
    previous_rows_.forget();
  }

  /// Shift-only (when refinement follows) registration of the current panorama against the
  /// previous frame and the robust linear fit. Keeps the current spectra as the candidate
  /// next reference (advance()). nullopt when the registration rejects the panorama or no
  /// previous frame is set. `fit_seconds` (optional): the fit's wall time.
  std::optional<MotionEstimate> firstPass(double* fit_seconds = nullptr);
  /// The same against keyframe `slot`, of the current panorama de-rotated by `R`
  /// (the current frame's spectra are not kept): the fit is the residual after R.
  std::optional<MotionEstimate> alignedPass(const Eigen::Matrix3d& R, int slot);
  /// Refinement passes of PipelineOptions::refine_iterations starting from `start` (the
  /// estimate whose windows() are the first pass's) at rotation `R` and translation `tau`,
  /// against `against` (WindowRegistration::kPreviousFrame or a keyframe slot).
  PassResult refine(const MotionEstimate& start, const Eigen::Matrix3d& R,
                    const Eigen::Vector3d& tau, int against) {
    return refineInto(start, R, tau, against, refine_windows_, refine_weights_);
  }
  /// The same into windows of its own: the windows of the last refine() stay those of its
  /// PassResult (a second registration of the current frame, against a keyframe, after the
  /// one whose windows are published).
  PassResult secondRefine(const MotionEstimate& start, const Eigen::Matrix3d& R,
                          const Eigen::Vector3d& tau, int against) {
    return refineInto(start, R, tau, against, second_windows_, second_weights_);
  }
  /// The candidate next reference (firstPass()) becomes the previous frame.
  void advance() {
    registration_.advance();
    keepPrevious();
    previous_rows_ = current_rows_;  // the same size: no allocation
  }

  /// Makes the previous frame (after advance() or makeCurrentPrevious(): the current one)
  /// keyframe `slot`, with the current panorama for the ring search. The panorama moves
  /// into the slot: panorama() is stale until the next unwrap(). Requires a previous frame.
  bool storeKeyframe(int slot);
  /// Makes `panorama` (CV_8UC1 or CV_32FC1 of the panorama's size: a place kept from
  /// earlier) keyframe `slot`: its spectra, its panorama for the ring search, its rows'
  /// rotation unknown. False for an unknown slot or a panorama of the wrong size.
  bool loadKeyframe(int slot, const cv::Mat& panorama);
  /// Yaw of the current panorama relative to keyframe `slot` from the whole-ring search,
  /// radians, about the camera's z axis; nullopt when the correlation peak is below
  /// `min_peak` or the slot is empty.
  std::optional<double> ringYaw(int slot, double min_peak);

  const Calibration& calibration() const { return calibration_; }
  const PipelineOptions& options() const { return options_; }
  const cv::Mat& panorama() const { return panorama_; }
  /// Windows of the last first pass (firstPass(), alignedPass()).
  std::span<const WindowMotion> firstPassWindows() const { return windows_; }
  int windowCount() const { return registration_.windowCount(); }
  double windowAttenuation() const { return fit_.kappa(); }
  int threads() const { return pool_.size(); }
  int activeThreads() const { return pool_.activeWorkers(); }
  /// Time the calling thread has waited for indices running on pool threads, seconds in all.
  double workerWaitSeconds() const { return pool_.waitSeconds(); }
  long framesWaitedForWorkers() const { return pool_.waitedBursts(); }
  bool wisdomLoaded() const { return wisdom_.loaded; }
  /// The windows' mean capture time after the frame's timestamp, seconds (the mean of their
  /// taper-weighted capture times, Calibration::captureTime()); 0 for a global shutter.
  double meanWindowTime() const { return mean_window_time_; }

 private:
  /// The FFTW wisdom file of PipelineOptions::fftw_wisdom ("" = none), read before any plan
  /// is made; written after planning when it was not read or planning added to it (best
  /// effort: an unwritable path only costs the determinism of the next start-up). A path
  /// that can never be the wisdom file (a symbolic link, a FIFO or device, a file of another
  /// kind, a missing directory) throws std::invalid_argument naming it.
  struct WisdomFile {
    explicit WisdomFile(std::string file);
    static bool checked(const std::string& path);
    runtime::PlanEffort effort() const;
    void saveIfPlanned() const;
    std::string path;
    bool loaded;         ///< the file was read
    std::string before;  ///< the process's wisdom after reading the file
  };

  static int bandStart(int b, int bands, int rows) { return b * rows / bands; }
  /// refine() with its passes' windows and weights in `windows` and `weights`.
  PassResult refineInto(const MotionEstimate& start, const Eigen::Matrix3d& R,
                        const Eigen::Vector3d& tau, int against,
                        std::vector<WindowMotion>& windows, std::vector<double>& weights);
  /// Fills window_times_ from the calibration's capture times (start-up).
  void measureWindowTimes();
  void predictRefinementShifts(const Eigen::Vector3d& tau, FitStatus last_fit);
  /// PipelineOptions::dewarp_by_fit: fills dewarp_ with the rotation and scale the motion
  /// left after the de-rotation by R_warp (R R_warp^T, tau at the last fit's inverse depths)
  /// makes in each window and returns the span for WindowRegistration::measure()'s `dewarp`;
  /// empty (each window de-warped by its own) when the option is off, the last fit was not
  /// kOk, or tau is within what R's tilt can make the first-order fit read (kSecondOrderMargin).
  std::span<const WindowMotion> predictDewarp(const Eigen::Matrix3d& R,
                                              const Eigen::Matrix3d& R_warp,
                                              const Eigen::Vector3d& tau, FitStatus last_fit);
  /// The shift (du, dv), pixels, that the motion (omega, tau) makes in window k at the last
  /// fit's inverse depth of that window.
  Eigen::Vector2d predictedShift(int k, const Eigen::Vector3d& omega,
                                 const Eigen::Vector3d& tau) const;
  /// The current panorama becomes previous_, the reference of the pixel checks
  /// (discountMovingContent(), measureVerticalScale()); nothing to keep when they are off.
  void keepPrevious() {
    if (options_.moving_content || options_.fit.vertical_scale) panorama_.copyTo(previous_);
  }
  /// The panorama the windows of a pass `against` were registered against: previous_ or the
  /// keyframe slot's.
  const cv::Mat& referencePanorama(int against) const;
  /// With MotionFit::Options::vertical_scale, each window's vertical scale (VerticalScale)
  /// between referencePanorama(against) and `current`, the panorama the pass measured.
  void measureVerticalScale(std::span<WindowMotion> windows, int against, const cv::Mat& current);
  /// `R` with its yaw (about the camera's z axis) rounded to whole panorama columns when its
  /// tilt is under one column's angle (else `R`): the de-rotation a refinement pass warps by.
  Eigen::Matrix3d wholeColumnYaw(const Eigen::Matrix3d& R) const;
  void derotate(const Eigen::Matrix3d& R);
  /// MovingContentCheck of `windows`, measured between the reference panorama of `against`
  /// and the de-rotated current one (warped_), into each window's moving_fraction, and its
  /// confidences lowered by MovingContentCheck::weight(). `R_residual` (the estimate after
  /// the de-rotation) and `tau` give each window's predicted shift.
  void discountMovingContent(std::span<WindowMotion> windows, int against,
                             const Eigen::Matrix3d& R_residual, const Eigen::Vector3d& tau);
  /// The motion fit of `windows`, its covariance multiplied by window_overlap_.
  MotionEstimate fitWindows(std::span<const WindowMotion> windows);
  /// The last fit's verdict on each of its `windows`: MotionFit::finalWeight() into
  /// `weights`, and moving_fraction 1 for the windows MotionFit::judgedMoving() (the ring
  /// consensus left them out: they moved as a whole, as no static scene does).
  void keepVerdicts(std::span<WindowMotion> windows, std::vector<double>& weights) const;
  /// The same with each window's rows scaled by row_scale_ (fitPass()).
  MotionEstimate fitScaled(std::span<const WindowMotion> windows);
  /// fitWindows() of the windows of a pass over the current panorama de-rotated by
  /// exp([warp_omega]x) (zero: not de-rotated), their du, dv first corrected in place for
  /// the times their rows were captured when the sensor has a readout time: the fit then
  /// gives the motion between the frames' timestamps (DESIGN.md section 3). `reference`:
  /// the rows of the frame registered against; with them and the current frame's known the
  /// correction is the gyro's (correctRowsWithGyro()).
  MotionEstimate fitPass(std::span<WindowMotion> windows, const Eigen::Vector3d& warp_omega,
                         const FrameRotation& reference);
  /// The windows' du, dv and rotation of a pass (fitPass()) less what the rotation within
  /// each frame up to the window's capture time made (`reference`'s rows and the current
  /// frame's), their translation stretched to the whole interval.
  void correctRowsWithGyro(std::span<WindowMotion> windows, const Eigen::Vector3d& warp_omega,
                           const FrameRotation& reference);
  /// `rows`' mean turn over the exposure about `s` seconds after its timestamp, its yaw read
  /// yaw_time_offset_ later (correctRowsWithGyro()).
  Eigen::Vector3d turnForYawAt(const FrameRotation& rows, double s) const;
  /// The rotation within the frame `against` (WindowRegistration::kPreviousFrame or a
  /// keyframe slot).
  const FrameRotation& rowsOf(int against) const {
    return against == WindowRegistration::kPreviousFrame
               ? previous_rows_
               : keyframe_rows_[static_cast<std::size_t>(against)];
  }
  /// The change b of the roll and pitch rates (rad/s, camera x and y) from the reference's
  /// interval to the current frame's that the dv of `windows` (fitPass(), the whole motion)
  /// show; nullopt when too few windows or an ill-posed regression.
  std::optional<Eigen::Vector2d> tiltRateChange(std::span<const WindowMotion> windows) const;

  Calibration calibration_;
  PipelineOptions options_;
  WisdomFile wisdom_;
  runtime::WorkerPool pool_;
  Unwrapper unwrapper_;
  WindowRegistration registration_;
  MotionFit fit_;
  /// windowOverlapFactor() of the registration's windows: neighbouring windows share
  /// pixels, so their errors are not independent as the fit's covariance assumes.
  double window_overlap_;
  PanoramaWarp warp_;
  std::optional<RingAlignment> ring_;
  MovingContentCheck moving_;
  VerticalScale vertical_;
  /// The current panorama, its de-rotation, and the previous frame's panorama (the
  /// reference of the pixel checks and the vertical scale against the previous frame).
  cv::Mat panorama_, warped_, previous_;
  std::vector<double> moving_fraction_;  ///< per window, discountMovingContent()
  std::vector<Eigen::Vector2d> expected_motion_;  ///< per window, discountMovingContent()
  std::vector<cv::Mat> keyframe_panoramas_;  ///< per keyframe slot
  std::vector<WindowMotion> windows_, refine_windows_, second_windows_;
  /// How much each window of windows_ / refine_windows_ / second_windows_ weighed in the fit
  /// of its pass (MotionFit::finalWeight()), kept after that pass's fit.
  std::vector<double> weights_, refine_weights_, second_weights_;
  std::vector<WindowMotion> shifts_only_;  ///< "known" rotation/scale for a shift-only pass
  std::vector<double> expected_dv_;        ///< refinement pass: dv per window, or NaN
  std::vector<WindowMotion> dewarp_;       ///< refinement pass: predictDewarp()'s per window
  std::vector<double> window_azimuth_;     ///< per window: azimuth of its centre, radians
  /// Per window: capture time of its pixels (taper-weighted mean, seconds after the frame's
  /// timestamp) and its change per panorama column and row; empty for a global shutter.
  struct WindowTime {
    double s = 0.0, ds_du = 0.0, ds_dv = 0.0;
  };
  std::vector<WindowTime> window_times_;
  /// Window k's capture time: window_times_[k], or the timestamp's (all zero) for a global
  /// shutter, whose rows are all captured then.
  WindowTime windowTime(std::size_t k) const {
    return window_times_.empty() ? WindowTime{} : window_times_[k];
  }
  double mean_window_time_ = 0.0;
  std::vector<MotionFit::RowScale> row_scale_;  ///< per window: the fit's row scale (fitPass())
  ShutterContext shutter_;
  /// Samples of each window's blur path over the exposure (setMotionBlur()).
  static constexpr int kBlurSamples = 32;
  /// Per window, kBlurSamples shifts over the current frame's exposure, pixels (du's sense).
  std::vector<float> blur_paths_;
  /// Gives the registration the current frame's horizontal blur path in every window from
  /// current_rows_ (or none when they are not known).
  void passMotionBlur();
  /// The rotation within the current frame, the previous one and each keyframe
  /// (measureRowRotations()).
  FrameRotation current_rows_, previous_rows_;
  std::vector<FrameRotation> keyframe_rows_;
  double yaw_time_offset_ = 0.0;  ///< seconds, setYawTimeOffset()
  bool last_pass_gyro_ = false;  ///< the last fitPass() was corrected with the gyro
  bool start_gyro_ = false;      ///< ... and the last firstPass() or alignedPass()
  bool has_previous_ = false;
};

}  // namespace omnipose::pipeline
