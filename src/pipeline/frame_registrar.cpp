#include "pipeline/frame_registrar.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <numbers>
#include <stdexcept>
#include <string>
#include <utility>

#include "omnipose/motion_model.hpp"
#include "omnipose/so3.hpp"
#include "registration/shared_pool_registration.hpp"
#include "runtime/fft_plan.hpp"

namespace omnipose::pipeline {
namespace {

/// The refinement pass's translation search is limited to a band of rows around the dv the
/// last fit predicts (WindowRegistration::measure(), expected_dv) when that prediction is
/// good to within the band: kPredictionSlackPx for the fit's error and the first-order
/// model, plus kDepthSpread times the predicted dv for the window's depth. Chosen from the
/// full-search dv of every window of the accuracy benchmark (docs/PERFORMANCE.md).
constexpr double kPredictionSlackPx = 4.0;
constexpr double kDepthSpread = 0.5;

/// tiltRateChange(): a rate change whose squared Mahalanobis norm is below this is noise.
constexpr double kTiltRateSignificance = 4.0;

/// wholeColumnYaw(): the largest tilt (radians) of a de-rotation whose yaw is rounded to whole
/// columns: 2 deg, above a tracked base's shaking between two frames (0.5 deg at up to 9 Hz
/// moves at most about 1 deg per frame at 30 fps).
constexpr double kWholeColumnMaxTilt = 2.0 * std::numbers::pi / 180.0;

/// predictDewarp(): the first pass's first-order fit reads a pair that tilts by a radians with
/// a translation that is not there of up to about 2.5 a^2 (random-axis turns of 1-6 deg a
/// frame; 0.003 at 5 deg of pitch); a translation under this many a^2 does not predict the
/// windows' scale.
constexpr double kSecondOrderMargin = 10.0;

/// The registration's options: each window's shift covariance is measured when the fit
/// uses it.
WindowRegistration::Options registrationOptions(const PipelineOptions& o) {
  WindowRegistration::Options r = o.registration;
  r.shift_covariance = r.shift_covariance || o.fit.window_covariance;
  return r;
}

/// The centre column of every window of `registration`.
std::vector<double> windowCenters(const WindowRegistration& registration) {
  std::vector<double> centers;
  for (int k = 0; k < registration.windowCount(); ++k)
    centers.push_back(registration.windowCenter(k));
  return centers;
}

}  // namespace

FrameRegistrar::WisdomFile::WisdomFile(std::string file)
    : path(std::move(file)),
      loaded(checked(path) && runtime::importWisdom(path)),
      before(loaded ? runtime::wisdomText() : std::string()) {}

bool FrameRegistrar::WisdomFile::checked(const std::string& path) {
  if (const std::optional<std::string> problem = runtime::wisdomFileProblem(path))
    throw std::invalid_argument("pipeline.fftw_wisdom: " + *problem);
  return true;
}

runtime::PlanEffort FrameRegistrar::WisdomFile::effort() const {
  // Plans that a file keeps are made once per machine: search them patiently. Without a
  // file every start-up plans again, so it measures only.
  return path.empty() ? runtime::PlanEffort::kMeasure : runtime::PlanEffort::kPatient;
}

void FrameRegistrar::WisdomFile::saveIfPlanned() const {
  if (!path.empty() && (!loaded || runtime::wisdomText() != before))
    (void)runtime::exportWisdom(path);
}

FrameRegistrar::FrameRegistrar(const Calibration& c, const PipelineOptions& o, int keyframe_slots)
    : calibration_(c),
      options_(o),
      wisdom_(o.fftw_wisdom),
      pool_(o.threads > 0 ? o.threads : runtime::WorkerPool::onlineCores()),
      unwrapper_(c, o.unwrap),
      registration_(SharedPoolRegistration::make(c.panorama.size(), registrationOptions(o), pool_,
                                                 wisdom_.effort())),
      fit_(o.fit, c.panorama.gamma(), o.registration.window, registration_.windowCount()),
      window_overlap_(windowOverlapFactor(o.registration.window, o.registration.step)),
      warp_(c.panorama),
      moving_(unwrapper_.validity(), o.registration.window, registration_.windowTop(),
              windowCenters(registration_)),
      vertical_(unwrapper_.validity(), o.registration.window, registration_.windowTop(),
                windowCenters(registration_), pool_.size()) {
  panorama_ = unwrapper_.makePanorama();
  warped_ = unwrapper_.makePanorama();
  previous_ = unwrapper_.makePanorama();
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
  second_windows_.resize(windows);
  weights_.resize(windows);
  refine_weights_.resize(windows);
  row_scale_.resize(windows);
  blur_paths_.resize(windows * kBlurSamples);
  second_weights_.resize(windows);
  shifts_only_.resize(windows);  // rs_confidence 0: no rotation/scale
  dewarp_.resize(windows);
  expected_dv_.resize(windows);
  moving_fraction_.resize(windows);
  expected_motion_.resize(windows);
  for (int k = 0; k < registration_.windowCount(); ++k)
    window_azimuth_.push_back(c.panorama.azimuth(registration_.windowCenter(k)));
  if (c.sensor.readout_s != 0.0) measureWindowTimes();
  current_rows_ = previous_rows_ =
      FrameRotation(c.sensor.readout_s, SensorTiming::kMaxExposureS);
  keyframe_rows_.assign(static_cast<std::size_t>(keyframe_slots), previous_rows_);
  wisdom_.saveIfPlanned();
}

void FrameRegistrar::measureWindowTimes() {
  // Capture time of every panorama pixel (through the lens model, as the unwrap table),
  // its gradient by central differences (u wraps around; one-sided at the top and bottom
  // rows), and per window the mean of both under the window's taper.
  const cv::Size size = calibration_.panorama.size();
  const int W = size.width, H = size.height, L = options_.registration.window;
  cv::Mat time(size, CV_64FC1);
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) time.at<double>(v, u) = calibration_.captureTime(u, v);
  const auto at = [&](int u, int v) { return time.at<double>(v, ((u % W) + W) % W); };
  const int top = registration_.windowTop(), windows = registration_.windowCount();
  window_times_.assign(static_cast<std::size_t>(windows), {});
  double sum_s = 0.0;  // over the windows the lens model sees
  int timed = 0;
  for (int k = 0; k < windows; ++k) {
    const int first = static_cast<int>(std::lround(registration_.windowCenter(k) - 0.5 * (L - 1)));
    double weight = 0.0, s = 0.0, ds_du = 0.0, ds_dv = 0.0;
    for (int i = 0; i < L; ++i) {
      const int v = top + i;
      for (int j = 0; j < L; ++j) {
        const int u = first + j;
        const double here = at(u, v);
        const double du = 0.5 * (at(u + 1, v) - at(u - 1, v));
        const double dv = v == 0 ? at(u, 1) - here
                          : v == H - 1 ? here - at(u, v - 1)
                                       : 0.5 * (at(u, v + 1) - at(u, v - 1));
        if (!std::isfinite(here) || !std::isfinite(du) || !std::isfinite(dv)) continue;
        const double w = windowTaper(i, L) * windowTaper(j, L);
        weight += w;
        s += w * here;
        ds_du += w * du;
        ds_dv += w * dv;
      }
    }
    if (weight > 0.0) {
      window_times_[static_cast<std::size_t>(k)] = {s / weight, ds_du / weight, ds_dv / weight};
      sum_s += s / weight;
      ++timed;
    }
  }
  mean_window_time_ = timed > 0 ? sum_s / timed : 0.0;
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

bool FrameRegistrar::measureRowRotations(std::span<const GyroSample> samples,
                                         const ImuCalibration& imu, const Eigen::Vector3d& bias,
                                         double time, double max_gap_s, double exposure_s) {
  if (!rowsMoveWithinFrame(exposure_s)) {
    forgetRowRotations();
    return false;
  }
  const bool known = current_rows_.measure(samples, imu, bias, time, max_gap_s, exposure_s);
  passMotionBlur();
  return known;
}

void FrameRegistrar::forgetRowRotations() {
  current_rows_.forget();
  passMotionBlur();
}

void FrameRegistrar::passMotionBlur() {
  if (!current_rows_.known() || !(current_rows_.exposure() > 0.0)) {
    registration_.setMotionBlur({}, 0);
    return;
  }
  // Window k's pixels, captured around s_k, are the mean of the sharp frames over the
  // exposure E centred there: the frame turned by turnAt(s_k + tau) - turnAt(s_k) (to first
  // order in the turn within E) shows each shifted as predictMotion() says.
  const double exposure = current_rows_.exposure(), gamma = calibration_.panorama.gamma();
  const int windows = registration_.windowCount();
  for (int k = 0; k < windows; ++k) {
    const auto i = static_cast<std::size_t>(k);
    const double s = windowTime(i).s;
    const Eigen::Vector3d centre = current_rows_.turnAt(s);
    for (int j = 0; j < kBlurSamples; ++j) {
      const double tau = exposure * ((j + 0.5) / kBlurSamples - 0.5);
      Eigen::Matrix<double, 6, 1> turn = Eigen::Matrix<double, 6, 1>::Zero();
      turn.head<3>() = current_rows_.turnAt(s + tau) - centre;
      blur_paths_[i * kBlurSamples + j] = static_cast<float>(
          predictMotion(turn, window_azimuth_[i], fit_.kappa()).du_rad / gamma);
    }
  }
  registration_.setMotionBlur(blur_paths_, kBlurSamples);
}

void FrameRegistrar::makeCurrentPrevious() {
  registration_.setReference(panorama_);
  keepPrevious();
  previous_rows_ = current_rows_;
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
  if (!shifts_only) measureVerticalScale(windows_, WindowRegistration::kPreviousFrame, panorama_);
  const auto t_fit = std::chrono::steady_clock::now();
  MotionEstimate estimate = fitPass(windows_, Eigen::Vector3d::Zero(), previous_rows_);
  keepVerdicts(windows_, weights_);
  start_gyro_ = last_pass_gyro_;
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
  if (!shifts_only) measureVerticalScale(windows_, slot, warped_);
  MotionEstimate estimate = fitPass(windows_, rotationVector(R), rowsOf(slot));
  keepVerdicts(windows_, weights_);
  start_gyro_ = last_pass_gyro_;
  return estimate;
}

void FrameRegistrar::keepVerdicts(std::span<WindowMotion> windows,
                                  std::vector<double>& weights) const {
  for (std::size_t k = 0; k < weights.size(); ++k) weights[k] = fit_.finalWeight(static_cast<int>(k));
  for (std::size_t k = 0; k < windows.size(); ++k)
    if (fit_.judgedMoving(static_cast<int>(k))) windows[k].moving_fraction = 1.0;
}

MotionEstimate FrameRegistrar::fitWindows(std::span<const WindowMotion> windows) {
  MotionEstimate estimate = fit_.fit(windows, calibration_.panorama.forward_column);
  estimate.covariance *= window_overlap_;
  return estimate;
}

void FrameRegistrar::correctRowsWithGyro(std::span<WindowMotion> windows,
                                         const Eigen::Vector3d& warp_omega,
                                         const FrameRotation& reference) {
  // Window k (capture time s_k after the timestamp, its gradient grad s) compares the
  // reference's pixels shifted by the registered (du, dv), captured at t_ref + s_k + g_r,
  // g_r = grad s . (du, dv), with the current frame's pixels of the window, captured at
  // t_cur + s_k + g_c: g_c = 0 in a pass over the current panorama itself, and after a
  // de-rotation that moved the window's pixels by the shift w, g_c = -grad s . w (they come
  // from where the de-rotation took them; a de-rotation's shift can be a large part of the
  // ring, so that time is read at the window's centre moved by w rather than along the
  // gradient). With A = R(t_ref)^T R(t_ref + s_k + g_r) and
  // B = R(t_cur)^T R(t_cur + s_k + g_c) from the gyro, the window sees the rotation A^T X B
  // of the motion X between the timestamps: C_k X with C_k = exp(-a_k) exp(X b_k). After a
  // de-rotation by R_w (X = E R_w) it sees exp(-a_k) E exp(R_w b_k), C_k E to first order in
  // the residual E: C_k with R_w for X, in the residual's frame. (c_k = X b_k - a_k, to first
  // order in the turns within the frames, is not enough: a turn of 3 deg per frame is
  // 40 mrad within a readout of 0.8 frames, and a_k x b_k / 2 is then 1e-4 rad.) The first pass
  // uses the gyro's X between the timestamps (bias errors there are second order). The
  // translation is measured over dt - g_r + g_c, as without the gyro (fitPass()): what is
  // left after the rotations is stretched to dt.
  const double dt = shutter_.interval_s, gamma = calibration_.panorama.gamma();
  const bool warped = !warp_omega.isZero();
  const Eigen::Matrix3d X = warped ? rotationFromVector(warp_omega)
                                   : shutter_.gyro_rotation.value_or(Eigen::Matrix3d::Identity());
  Eigen::Matrix<double, 6, 1> estimate = Eigen::Matrix<double, 6, 1>::Zero();
  estimate.head<3>() = rotationVector(X);
  for (std::size_t k = 0; k < windows.size(); ++k) {
    row_scale_[k] = {1.0, 1.0};
    WindowMotion& m = windows[k];
    if (!m.valid) continue;
    const WindowTime w = windowTime(k);
    const double theta = window_azimuth_[k];
    const ModelMotion rotated = predictMotion(estimate, theta, fit_.kappa());
    // The whole shift: a de-rotated pass's residual plus the de-rotation.
    const double w_du = warped ? rotated.du_rad / gamma : 0.0;
    const double w_dv = warped ? rotated.dv_rad / gamma : 0.0;
    const double du = m.du + w_du, dv = m.dv + w_dv;
    const double g_r = w.ds_du * m.du + w.ds_dv * m.dv;
    double g_c = 0.0;
    if (warped) {
      const double u = registration_.windowCenter(static_cast<int>(k));
      const double v = registration_.windowTop() + 0.5 * (options_.registration.window - 1);
      g_c = calibration_.captureTime(u - w_du, v - w_dv) - calibration_.captureTime(u, v);
      if (!std::isfinite(g_c)) g_c = -(w.ds_du * w_du + w.ds_dv * w_dv);
    }
    const double g = g_r - g_c;
    const double stretch = std::abs(g) < 0.5 * dt ? dt / (dt - g) : 1.0;
    Eigen::Matrix<double, 6, 1> within = Eigen::Matrix<double, 6, 1>::Zero();
    within.head<3>() =
        rotationVector(rotationFromVector(-turnForYawAt(reference, w.s + g_r)) *
                       rotationFromVector(X * turnForYawAt(current_rows_, w.s + g_c)));
    const ModelMotion c = predictMotion(within, theta, fit_.kappa());
    // The translation's part: the shift less the rotations.
    const double du_t = du - c.du_rad / gamma - rotated.du_rad / gamma;
    const double dv_t = dv - c.dv_rad / gamma - rotated.dv_rad / gamma;
    m.du = du_t * stretch + (warped ? 0.0 : rotated.du_rad / gamma);
    m.dv = dv_t * stretch + (warped ? 0.0 : rotated.dv_rad / gamma);
    m.rotation -= c.rotation;
  }
}

Eigen::Vector3d FrameRegistrar::turnForYawAt(const FrameRotation& rows, double s) const {
  Eigen::Vector3d turn = rows.exposedTurnAt(s);
  if (yaw_time_offset_ != 0.0) turn.z() = rows.exposedTurnAt(s + yaw_time_offset_).z();
  return turn;
}

MotionEstimate FrameRegistrar::fitPass(std::span<WindowMotion> windows,
                                       const Eigen::Vector3d& warp_omega,
                                       const FrameRotation& reference) {
  last_pass_gyro_ = false;
  if (!(shutter_.interval_s > 0.0)) return fitWindows(windows);
  if (reference.known() && current_rows_.known()) {
    correctRowsWithGyro(windows, warp_omega, reference);
    last_pass_gyro_ = true;
    return fitScaled(windows);
  }
  if (window_times_.empty()) return fitWindows(windows);
  // Window k compares the reference's rows captured at t_ref + s(c + d) with the current
  // frame's at t_cur + s(c): it measures the motion over [t_ref + s_k + g_k, t_cur + s_k],
  // g_k = grad s . d (d: its whole shift, the de-rotation's included). With the velocity
  // linear in time that is A_k (X + s_k b) (dt - g_k) / dt, with X the motion between the
  // timestamps, A_k the window's model rows and b = v(t_cur) - v(t_ref).
  // - du (yaw, horizontal translation): with s_k = s_m + e_k, s_m the windows' mean capture
  //   time, A_k (X + s_k b) = A_k (X_m + e_k b), X_m the motion between t_ref + s_m and
  //   t_cur + s_m. The pair gives X_m; e_k b is a first harmonic around the ring, which a
  //   horizontal translation also makes, so b is taken from v running through the previous
  //   pair's mean velocity v_p and this pair's, X_m / dt, at the midpoints of their
  //   intervals: b = c (X_m / dt - v_p), c = 2 dt / (dt + dt_p), so (1 + e_k c / dt) A_k X_m
  //   = d_k dt / (dt - g_k) + e_k c A_k v_p, linear in X_m: the fit solves it with the du
  //   rows scaled (the harmonic the rate change makes is not read as translation). The fit's
  //   yaw is then X_m's, which ReadoutYaw moves to the timestamps from consecutive pairs
  //   (roll and pitch are the timestamps' already, through the dv regression below). Without
  //   a previous pair (c = 0) only the stretch is corrected.
  // - dv (roll, pitch, vertical translation): a tracked base shakes faster than a frame, so
  //   b comes from the pair itself (tiltRateChange()).
  const double dt = shutter_.interval_s, gamma = calibration_.panorama.gamma();
  const double c = shutter_.previous_interval_s > 0.0
                       ? 2.0 * dt / (dt + shutter_.previous_interval_s)
                       : 0.0;
  Eigen::Matrix<double, 6, 1> warp;
  warp << warp_omega, Eigen::Vector3d::Zero();
  for (std::size_t k = 0; k < windows.size(); ++k) {
    const WindowTime& w = window_times_[k];
    const double e = w.s - mean_window_time_;
    row_scale_[k] = {1.0 + e * c / dt, 1.0};
    WindowMotion& m = windows[k];
    if (!m.valid) continue;
    const double theta = window_azimuth_[k];
    const ModelMotion removed = predictMotion(warp, theta, fit_.kappa());
    const double du = m.du + removed.du_rad / gamma, dv = m.dv + removed.dv_rad / gamma;
    const double g = w.ds_du * du + w.ds_dv * dv;
    const double stretch = std::abs(g) < 0.5 * dt ? dt / (dt - g) : 1.0;
    Eigen::Matrix<double, 6, 1> v = shutter_.previous_velocity * (e * c);
    v.tail<3>() *= fit_.inverseDepth(static_cast<int>(k));
    const ModelMotion before = predictMotion(v, theta, fit_.kappa());
    m.du = du * stretch + before.du_rad / gamma - row_scale_[k].du * removed.du_rad / gamma;
    m.dv = dv * stretch - removed.dv_rad / gamma;
  }
  if (const std::optional<Eigen::Vector2d> b = tiltRateChange(windows)) {
    // Take the roll and pitch that changed speed during the pair out of every window: the
    // fit then gives the motion between the timestamps.
    for (std::size_t k = 0; k < windows.size(); ++k) {
      if (!windows[k].valid) continue;
      Eigen::Matrix<double, 6, 1> x;
      x << window_times_[k].s * *b, 0.0, 0.0, 0.0, 0.0;
      const double theta = window_azimuth_[k];
      const ModelMotion m = predictMotion(x, theta, fit_.kappa());
      windows[k].dv -= m.dv_rad / gamma;
      windows[k].rotation -= m.rotation;
    }
  }
  return fitScaled(windows);
}

MotionEstimate FrameRegistrar::fitScaled(std::span<const WindowMotion> windows) {
  const std::span<const MotionFit::RowScale> scale(row_scale_.data(), windows.size());
  MotionEstimate estimate = fit_.fit(windows, calibration_.panorama.forward_column, scale);
  estimate.covariance *= window_overlap_;
  return estimate;
}

std::optional<Eigen::Vector2d> FrameRegistrar::tiltRateChange(
    std::span<const WindowMotion> windows) const {
  // Window k sees roll and pitch over [t_ref + s_k, t_cur + s_k]: with their rates changing
  // by b (rad/s) from the first interval to the second, its dv is A_k (X + s_k (b, 0)).
  // s_k = c0 + c1 sin(image angle): the c0 part is a roll and pitch that cannot be told
  // from the motion's own, the c1 part makes harmonics of 2 theta in dv, which nothing
  // else in the model makes. So regressing dv on s_k A_k (b, 0) beside the model's own dv
  // terms (1, sin, cos: roll, pitch, vertical translation at the mean depth) gives b; twice,
  // the second time without the windows beyond 3 robust sigmas. (The fit's own residuals
  // would not do: its per-window depths can absorb the harmonics through the vertical
  // translation.) Yaw's rate change is not taken from the pair: in du its c1 part looks
  // like a translation.
  const double gamma = calibration_.panorama.gamma(), kappa = fit_.kappa();
  using Vec5 = Eigen::Matrix<double, 5, 1>;
  const auto basis = [&](std::size_t k) {
    const double theta = window_azimuth_[k];
    const double sn = kappa * std::sin(theta), cs = kappa * std::cos(theta);
    const double s_k = window_times_[k].s;
    Vec5 f;
    f << -s_k * sn, s_k * cs, 1.0, sn, cs;
    return f;
  };
  // Round 0 fits all windows, round 1 the ones within 3 robust sigmas of round 0's fit
  // (cutoff), round 2 only measures the noise of round 1's fit.
  double cutoff = std::numeric_limits<double>::infinity(), noise = 0.0;
  Vec5 solution = Vec5::Zero();
  Eigen::Matrix<double, 5, 5> normal;
  for (int round = 0; round < 3; ++round) {
    normal.setZero();
    Vec5 rhs = Vec5::Zero();
    int used = 0;
    double sum_sq = 0.0, sum_wsq = 0.0;
    for (std::size_t k = 0; k < windows.size(); ++k) {
      if (!windows[k].valid || !(windows[k].confidence > 0.0)) continue;
      const Vec5 f = basis(k);
      const double dv = windows[k].dv * gamma;
      const double r = dv - f.dot(solution);
      if (round > 0 && !(std::abs(r) <= cutoff)) continue;
      const double w = windows[k].confidence;
      normal.noalias() += w * f * f.transpose();
      rhs += w * dv * f;
      sum_sq += r * r;
      sum_wsq += w * r * r;
      ++used;
    }
    if (used < MotionFit::kMinWindows) return std::nullopt;
    if (round == 2) {
      noise = sum_wsq / (used - 5);
      break;
    }
    const Eigen::LDLT<Eigen::Matrix<double, 5, 5>> ldlt(normal);
    if (ldlt.info() != Eigen::Success || !(ldlt.rcond() > 1e-12)) return std::nullopt;
    solution = ldlt.solve(rhs);
    if (round == 0) cutoff = 3.0 * std::sqrt(sum_sq / used);
  }
  if (!solution.allFinite()) return std::nullopt;
  // Shrunk by its own significance: a rate change within the noise (a camera that does not
  // shake) would only add that noise to the tilt. d2 = b^T Cov(b)^-1 b; at 2 sigmas and
  // below b is dropped, well above it kept nearly whole.
  const Eigen::Matrix<double, 5, 5> covariance = noise * normal.inverse();
  const Eigen::Vector2d b(solution(0), solution(1));
  const Eigen::Matrix2d cov_b = covariance.topLeftCorner<2, 2>();
  const double d2 = b.dot(cov_b.ldlt().solve(b));
  if (!(d2 > kTiltRateSignificance)) return std::nullopt;
  return b * (1.0 - kTiltRateSignificance / d2);
}

PassResult FrameRegistrar::refineInto(const MotionEstimate& start, const Eigen::Matrix3d& R0,
                                      const Eigen::Vector3d& tau0, int against,
                                      std::vector<WindowMotion>& windows,
                                      std::vector<double>& weights) {
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
  out.window_weights = weights_;
  out.window_model = start.vector();
  out.gyro_rows = start_gyro_;
  for (int pass = 0; pass < options_.refine_iterations && est.status != FitStatus::kLost; ++pass) {
    const Eigen::Matrix3d R_warp = wholeColumnYaw(R);
    derotate(R_warp);
    predictRefinementShifts(tau, last_fit);
    if (!registration_.measure(warped_, windows, false, {}, expected_dv_, against,
                               predictDewarp(R, R_warp, tau, last_fit)))
      break;
    measureVerticalScale(windows, against, warped_);
    if (options_.moving_content)
      discountMovingContent(windows, against, R * R_warp.transpose(), tau);
    const MotionEstimate residual = fitPass(windows, rotationVector(R_warp), rowsOf(against));
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
    keepVerdicts(windows, weights);
    out.windows = windows;
    out.window_weights = weights;
    out.window_model = residual.vector();
    out.gyro_rows = last_pass_gyro_;
  }
  est.omega = rotationVector(R);
  est.tau = tau;
  out.estimate = est;
  out.rotation = R;
  return out;
}

const cv::Mat& FrameRegistrar::referencePanorama(int against) const {
  return against == WindowRegistration::kPreviousFrame
             ? previous_
             : keyframe_panoramas_[static_cast<std::size_t>(against)];
}

void FrameRegistrar::measureVerticalScale(std::span<WindowMotion> windows, int against,
                                          const cv::Mat& current) {
  if (options_.fit.vertical_scale && options_.fit.use_rotation_scale)
    vertical_.measure(referencePanorama(against), current, windows, pool_);
}

void FrameRegistrar::discountMovingContent(std::span<WindowMotion> windows, int against,
                                           const Eigen::Matrix3d& R_residual,
                                           const Eigen::Vector3d& tau) {
  const cv::Mat& reference = referencePanorama(against);
  // What the estimate so far predicts each window measured: the rotation the de-rotation
  // left, and the translation at the window's inverse depth of the last fit.
  const Eigen::Vector3d omega = rotationVector(R_residual);
  for (std::size_t k = 0; k < windows.size(); ++k)
    expected_motion_[k] = predictedShift(static_cast<int>(k), omega, tau);
  moving_.measure(reference, warped_, warp_, windows, pool_, moving_fraction_, expected_motion_);
  for (std::size_t k = 0; k < windows.size(); ++k) {
    WindowMotion& m = windows[k];
    m.moving_fraction = moving_fraction_[k];
    const double weight = MovingContentCheck::weight(m.moving_fraction);
    m.confidence *= weight;
    m.rs_confidence *= weight;
  }
}

bool FrameRegistrar::storeKeyframe(int slot) {
  if (!has_previous_ || !registration_.storeKeyframe(slot)) return false;
  keyframe_rows_[static_cast<std::size_t>(slot)] = previous_rows_;
  std::swap(panorama_, keyframe_panoramas_[static_cast<std::size_t>(slot)]);  // headers only
  return true;
}

bool FrameRegistrar::loadKeyframe(int slot, const cv::Mat& panorama) {
  if (slot < 0 || slot >= static_cast<int>(keyframe_panoramas_.size()) ||
      panorama.size() != panorama_.size() ||
      (panorama.type() != CV_8UC1 && panorama.type() != CV_32FC1))
    return false;
  cv::Mat& kept = keyframe_panoramas_[static_cast<std::size_t>(slot)];
  panorama.convertTo(kept, CV_32F);  // the same size and type: no allocation
  keyframe_rows_[static_cast<std::size_t>(slot)].forget();
  return registration_.setKeyframe(slot, kept);
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
  // same fraction every frame (a steady turn) adds up. A whole-column yaw leaves the
  // horizontal fraction at (nearly) zero; the residual fit measures the rest
  // (docs/results/ANALYSIS.md). Also under a tilt: on a shaking base the horizontal
  // fraction is still the yaw's, and a turn swinging +-120 deg under 0.5 deg of vibration
  // read every turn 0.1 % long without it. Not under large tilts (kWholeColumnMaxTilt),
  // where rounding cost roll in the accuracy benchmark.
  if (tiltAngle(R) > kWholeColumnMaxTilt) return R;
  const double gamma = calibration_.panorama.gamma();
  const double yaw = std::atan2(R(1, 0), R(0, 0));
  const double rounded = std::round(yaw / gamma) * gamma;
  return Eigen::AngleAxisd(rounded - yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix() * R;
}

Eigen::Vector2d FrameRegistrar::predictedShift(int k, const Eigen::Vector3d& omega,
                                               const Eigen::Vector3d& tau) const {
  Eigen::Matrix<double, 6, 1> x;
  x << omega, fit_.inverseDepth(k) * tau;
  const ModelMotion m =
      predictMotion(x, window_azimuth_[static_cast<std::size_t>(k)], fit_.kappa());
  return Eigen::Vector2d(m.du_rad, m.dv_rad) / calibration_.panorama.gamma();
}

void FrameRegistrar::predictRefinementShifts(const Eigen::Vector3d& tau, FitStatus last_fit) {
  if (last_fit != FitStatus::kOk) {
    std::fill(expected_dv_.begin(), expected_dv_.end(), std::numeric_limits<double>::quiet_NaN());
    return;
  }
  for (int k = 0; k < registration_.windowCount(); ++k) {
    const double dv = predictedShift(k, Eigen::Vector3d::Zero(), tau).y();
    const bool tight = kPredictionSlackPx + kDepthSpread * std::abs(dv) <=
                       WindowRegistration::kExpectedDvReachPx;
    expected_dv_[k] = tight ? dv : std::numeric_limits<double>::quiet_NaN();
  }
}

std::span<const WindowMotion> FrameRegistrar::predictDewarp(const Eigen::Matrix3d& R,
                                                            const Eigen::Matrix3d& R_warp,
                                                            const Eigen::Vector3d& tau,
                                                            FitStatus last_fit) {
  if (!options_.dewarp_by_fit || last_fit != FitStatus::kOk) return {};
  // The translation the tilt can make the first pass read (kSecondOrderMargin) must be below
  // the one it read, or below one too small to de-scale any window (its corners by 0.1 px).
  double nearest = 0.0;  // the largest inverse depth
  for (std::size_t k = 0; k < dewarp_.size(); ++k)
    nearest = std::max(nearest, fit_.inverseDepth(static_cast<int>(k)));
  const double negligible = nearest > 0.0 ? registration_.minDewarp() / (fit_.kappa() * nearest)
                                          : std::numeric_limits<double>::infinity();
  const double tilt = tiltAngle(R);
  if (kSecondOrderMargin * tilt * tilt > std::max(tau.norm(), negligible)) return {};
  Eigen::Matrix<double, 6, 1> x;
  x.head<3>() = rotationVector(R * R_warp.transpose());
  for (std::size_t k = 0; k < dewarp_.size(); ++k) {
    x.tail<3>() = fit_.inverseDepth(static_cast<int>(k)) * tau;
    const ModelMotion m = predictMotion(x, window_azimuth_[k], fit_.kappa());
    dewarp_[k].rotation = m.rotation;
    dewarp_[k].scale = std::exp(m.log_scale);
  }
  return dewarp_;
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
