#include "daemon/processor.hpp"

#include <time.h>

#include <cmath>
#include <limits>

#include "omnipose/fit_diagnostics_t.hpp"
#include "omnipose/motion_model.hpp"
#include "omnipose/pose_t.hpp"
#include "omnipose/status_t.hpp"

namespace omnipose::daemon {
namespace {

/// `T` as a pose_t quaternion (w, x, y, z) and position.
void writePose(const Eigen::Isometry3d& T, double (&orientation)[4], double (&position)[3]) {
  const Eigen::Quaterniond q(T.rotation());
  orientation[0] = q.w();
  orientation[1] = q.x();
  orientation[2] = q.y();
  orientation[3] = q.z();
  for (int i = 0; i < 3; ++i) position[i] = T.translation()[i];
}

/// Longest last_error / source text carried by status_t (longer text is truncated).
constexpr std::size_t kMaxText = 512;

std::int8_t toLcmStatus(FitStatus status) {
  switch (status) {
    case FitStatus::kOk: return pose_t::STATUS_OK;
    case FitStatus::kDegraded: return pose_t::STATUS_DEGRADED;
    case FitStatus::kLost: return pose_t::STATUS_LOST;
  }
  return pose_t::STATUS_LOST;
}

double millisSince(SteadyClock::time_point start) {
  return std::chrono::duration<double, std::milli>(SteadyClock::now() - start).count();
}

/// A CPU-time clock (CLOCK_THREAD_CPUTIME_ID, CLOCK_PROCESS_CPUTIME_ID), nanoseconds; 0 if
/// it cannot be read.
std::int64_t cpuTimeNs(clockid_t clock) {
  timespec ts{};
  if (clock_gettime(clock, &ts) != 0) return 0;
  return static_cast<std::int64_t>(ts.tv_sec) * 1'000'000'000 + ts.tv_nsec;
}

}  // namespace

Processor::Processor(const Calibration& calibration, const OdometryOptions& odometry,
                     const LcmConfig& lcm, MessageSink& sink, StatusBoard& board,
                     const std::string& source_description, GyroQueue* gyro,
                     const MapFileConfig& map_file)
    : odometry_(calibration, odometry),
      lcm_(lcm),
      sink_(sink),
      board_(board),
      diagnostics_(!lcm.fit_channel.empty()),
      gyro_(gyro),
      pose_(std::make_unique<pose_t>()),
      status_(std::make_unique<status_t>()),
      diagnostics_msg_(std::make_unique<fit_diagnostics_t>()),
      pictures_(lcm.panorama_channel.empty()
                    ? nullptr
                    : std::make_unique<PanoramaPictures>(calibration,
                                                         odometry.pipeline.unwrap.input,
                                                         lcm.panorama_hz, lcm.panorama_width)),
      error_text_(kMaxText + 1, '\0'),
      started_(SteadyClock::now()),
      last_status_time_(started_) {
  if (!map_file.path.empty() && odometry.loop_closure.enabled) {
    map_keeper_ = std::make_unique<MapKeeper>(map_file, odometry.loop_closure.max_places, board_);
    map_keeper_->load(odometry_, calibration);
  }
  load_.process_cpu_ns = cpuTimeNs(CLOCK_PROCESS_CPUTIME_ID);
  load_at_start_ = load_at_status_ = load_;
  *pose_ = pose_t{};
  pose_buffer_.resize(static_cast<std::size_t>(pose_->getEncodedSize()));

  *status_ = status_t{};
  status_->source = source_description.substr(0, kMaxText);
  status_->last_error.reserve(kMaxText);
  status_->last_error.assign(kMaxText, 'x');  // size the buffer for the longest text
  status_buffer_.resize(static_cast<std::size_t>(status_->getEncodedSize()));
  status_->last_error.clear();  // keeps its capacity

  // Diagnostics arrays are sized once for the (constant) window count.
  fit_diagnostics_t& d = *diagnostics_msg_;
  d = fit_diagnostics_t{};
  const int windows = odometry_.windowCount();
  d.num_windows = static_cast<std::int16_t>(windows);
  for (auto* v : {&d.center_u, &d.du, &d.dv, &d.rotation, &d.scale, &d.confidence,
                  &d.model_du, &d.model_dv, &d.weight, &d.moving_fraction}) {
    v->assign(static_cast<std::size_t>(windows), 0.0f);
  }
  d.valid.assign(static_cast<std::size_t>(windows), 0);
  d.masked.assign(static_cast<std::size_t>(windows), 0);
  d.gamma = calibration.panorama.gamma();
  d.forward_column = calibration.panorama.forward_column;
  diagnostics_buffer_.resize(static_cast<std::size_t>(d.getEncodedSize()));
}

Processor::~Processor() = default;

void Processor::finish() {
  if (map_keeper_) map_keeper_->saveNow(odometry_);
}

bool Processor::publish(const std::string& channel, std::span<const std::uint8_t> message) {
  if (!sink_.publish(channel, message.data(), message.size())) {
    ++board_.publish_failures;
    const char* why = sink_.lastError();
    board_.reportError("cannot publish a message on channel %s%s%s", channel.c_str(),
                       *why ? ": " : "", why);
    return false;
  }
  ++board_.messages_published;
  return true;
}

void Processor::pictures(const MailboxFrame& frame) {
  if (const std::span<const std::uint8_t> picture = pictures_->ready(); !picture.empty()) {
    publish(lcm_.panorama_channel, picture);
    pictures_->done();
  }
  pictures_->offer(*frame.image, frame.info.capture_time_us,
                   static_cast<std::int64_t>(frame.info.sequence));
}

bool Processor::publish(const std::string& channel, std::vector<std::uint8_t>& buffer,
                        int size) {
  if (size < 0) {
    ++board_.publish_failures;
    board_.reportError("cannot encode a message on channel %s", channel.c_str());
    return false;
  }
  return publish(channel, std::span<const std::uint8_t>(buffer.data(), static_cast<std::size_t>(size)));
}

void Processor::takeGyro() {
  if (gyro_ == nullptr) return;
  for (std::size_t n; (n = gyro_->pop(gyro_batch_)) > 0;)
    odometry_.addGyro(std::span<const GyroSample>(gyro_batch_.data(), n));
}

void Processor::countGyro(const FrameStamp& stamp) {
  const GyroCounters c = odometry_.gyroCounters();
  const auto sequence = static_cast<unsigned long long>(stamp.sequence);
  if (c.exposures_refused != exposures_refused_) {
    exposures_refused_ = c.exposures_refused;
    board_.reportError("frame %llu: its source reported an exposure of %g s, not in [0, %g] s: "
                       "modelled with the calibration's sensor.exposure_s",
                       sequence, stamp.exposure_s, SensorTiming::kMaxExposureS);
  }
  board_.imu_samples.store(c.accepted);
  board_.imu_samples_refused.store(c.not_finite + c.too_fast + c.out_of_order);
  board_.imu_clock_restarts.store(c.clock_restarts);
  board_.frames_with_gyro.store(c.frames_with_gyro);
  board_.frames_without_gyro.store(c.frames_without_gyro);
  board_.frames_gyro_bridged.store(c.frames_gyro_bridged);
  // The frame when the gyro's samples did not cover it (with a stream configured).
  if (gyro_ == nullptr || c.frames_without_gyro == frames_without_gyro_) return;
  frames_without_gyro_ = c.frames_without_gyro;
  board_.reportError("frame %llu: the gyro's samples do not cover its readout (the newest at "
                     "%.6f s on the IMU's clock, the frame at %.6f s): registered from the "
                     "images alone",
                     sequence, c.last_sample_t, stamp.time_s);
}

void Processor::countMap(const OdometryResult& r) {
  board_.places.store(r.places);
  if (r.loop_closed) ++board_.loops_closed;
  const LoopClosureCounters c = odometry_.loopClosureCounters();
  board_.map_registrations.store(c.compared);
  board_.map_refused_no_heading.store(c.no_ring_peak);
  board_.map_refused_turned.store(c.turned_too_far);
  board_.map_refused_fit.store(c.fit_failed);
  board_.map_refused_too_far.store(c.too_far);
  board_.map_verified.store(c.verified);
  board_.map_disagreed.store(c.disagreed);
}

FrameStamp Processor::stampOf(const MailboxFrame& frame) {
  const FrameInfo& info = frame.info;
  // The recording's own timestamps when there are some (a hole in a recording replayed as
  // fast as possible is still a hole), else the capture time on the clock that does not
  // jump (the gyro's samples are joined to it), else the wall clock's.
  const double t = info.index >= 0            ? info.source_timestamp
                   : info.steady_time_us > 0 ? static_cast<double>(info.steady_time_us) * 1e-6
                                             : static_cast<double>(info.capture_time_us) * 1e-6;
  return {.time_s = t,
          .sequence = static_cast<std::int64_t>(info.sequence),
          .gap_before = frame.gap_before,
          .exposure_s = info.exposure_s};
}

void Processor::handleFrame(const MailboxFrame& frame) {
  const auto t_start = SteadyClock::now();
  const FrameInfo& info = frame.info;
  const FrameStamp stamp = stampOf(frame);
  takeGyro();

  const std::int64_t cpu_start = cpuTimeNs(CLOCK_THREAD_CPUTIME_ID);
  Expected<OdometryResult> result = odometry_.process(*frame.image, stamp);
  load_.processing_cpu_ns += cpuTimeNs(CLOCK_THREAD_CPUTIME_ID) - cpu_start;
  countGyro(stamp);
  load_.processing_wall_ns +=
      std::chrono::duration_cast<std::chrono::nanoseconds>(SteadyClock::now() - t_start).count();
  ++load_.frames;
  if (!result) {
    ++board_.frames_bad;
    if (result.error().code() == ErrorCode::kImplausible) ++board_.frames_implausible;
    if (info.index >= 0) {
      board_.reportError("frame %llu (dataset index %d): %s",
                         static_cast<unsigned long long>(info.sequence), info.index,
                         result.error().c_str());
    } else {
      board_.reportError("frame %llu: %s", static_cast<unsigned long long>(info.sequence),
                         result.error().c_str());
    }
    return;  // the odometry bridges the next good frame
  }
  const OdometryResult& r = *result;
  const FrameMotion& motion = r.relative;
  const MotionEstimate& est = motion.estimate;

  pose_t& p = *pose_;
  p.utime = info.capture_time_us;
  p.sequence = static_cast<std::int64_t>(info.sequence);
  p.source_index = info.index;
  p.source_timestamp = info.source_timestamp;
  p.frames_skipped = static_cast<std::int32_t>(frame.skipped_before);
  p.windows_total = static_cast<std::int16_t>(odometry_.windowCount());
  p.track_state = static_cast<std::int8_t>(r.state);
  p.keyframe_sequence = r.keyframe_sequence;
  p.frames_since_keyframe = r.frames_since_keyframe;

  if (!r.tracked()) {
    // Segment start: no relative motion, infinite uncertainty, pose held.
    p.status = pose_t::STATUS_LOST;
    p.reference_sequence = -1;
    for (int i = 0; i < 3; ++i) p.rotation_vector[i] = p.translation_direction[i] = 0.0;
    p.tau_norm = 0.0;
    for (int i = 0; i < 36; ++i) {
      p.covariance[i] = (i % 7 == 0) ? std::numeric_limits<double>::infinity() : 0.0;
    }
    p.residual_px = static_cast<float>(est.residual_rms_px);
    p.windows_used = 0;
    ++board_.poses_lost;
  } else {
    p.status = toLcmStatus(est.status);
    p.reference_sequence = r.reference_sequence;
    for (int i = 0; i < 3; ++i) {
      p.rotation_vector[i] = est.omega[i];
      p.translation_direction[i] = motion.translation_direction[i];
    }
    p.tau_norm = motion.tau_norm;
    for (int row = 0; row < 6; ++row)
      for (int c = 0; c < 6; ++c) p.covariance[row * 6 + c] = est.covariance(row, c);
    p.residual_px = static_cast<float>(est.residual_rms_px);
    p.windows_used = static_cast<std::int16_t>(est.windows_used);
  }
  p.segment = r.segment;
  writePose(r.pose, p.orientation, p.position);
  writePose(r.map_pose, p.map_orientation, p.map_position);
  writePose(r.map_correction, p.map_correction_orientation, p.map_correction_position);
  p.loop_closed = r.loop_closed;
  p.loop_place_sequence = r.loop_place_sequence;
  p.places = r.places;
  p.relocalising = r.relocalising;
  countMap(r);
  p.processing_time_s = static_cast<float>(motion.timing.total);

  const int size = p.encode(pose_buffer_.data(), 0, static_cast<int>(pose_buffer_.size()));
  publish(lcm_.pose_channel, pose_buffer_, size);
  board_.segment.store(p.segment);
  ++board_.frames_processed;
  latency_ms_.add(static_cast<float>(wallClockMicros() - info.capture_time_us) * 1e-3f);

  if (diagnostics_ && r.tracked() && !r.windows.empty()) {  // a gyro bridge measured none
    fillDiagnostics(info, r, p.status);
    const int n = diagnostics_msg_->encode(diagnostics_buffer_.data(), 0,
                                           static_cast<int>(diagnostics_buffer_.size()));
    publish(lcm_.fit_channel, diagnostics_buffer_, n);
  }
  if (pictures_) pictures(frame);
  if (map_keeper_) map_keeper_->afterFrame(odometry_, r, info.sequence, SteadyClock::now());
  processing_ms_.add(static_cast<float>(millisSince(t_start)));
}

void Processor::fillDiagnostics(const FrameInfo& info, const OdometryResult& r,
                                std::int8_t status) {
  fit_diagnostics_t& d = *diagnostics_msg_;
  const MotionEstimate& est = r.relative.estimate;
  d.utime = info.capture_time_us;
  d.sequence = static_cast<std::int64_t>(info.sequence);
  d.status = status;
  for (int i = 0; i < 3; ++i) {
    d.omega[i] = est.omega[i];
    d.tau[i] = est.tau[i];
  }
  d.residual_px = static_cast<float>(est.residual_rms_px);
  d.windows_masked = static_cast<std::int16_t>(est.windows_masked);
  d.refined = r.windows_refined;
  d.reference_sequence = r.windows_reference_sequence;
  const std::size_t n = std::min(r.windows.size(), d.du.size());
  for (std::size_t k = 0; k < n; ++k) {
    const WindowMotion& w = r.windows[k];
    d.center_u[k] = static_cast<float>(w.center_u);
    d.du[k] = static_cast<float>(w.du);
    d.dv[k] = static_cast<float>(w.dv);
    d.rotation[k] = static_cast<float>(w.rotation);
    d.scale[k] = static_cast<float>(w.scale);
    d.confidence[k] = static_cast<float>(w.confidence);
    d.valid[k] = w.valid ? 1 : 0;
    d.masked[k] = w.masked ? 1 : 0;
    d.weight[k] = k < r.window_weights.size() ? static_cast<float>(r.window_weights[k]) : 0.0f;
    d.moving_fraction[k] = static_cast<float>(w.moving_fraction);
    const Eigen::Vector2d model = predictWindowShiftPx(
        r.window_model, w.center_u, d.forward_column, d.gamma, odometry_.windowAttenuation());
    d.model_du[k] = static_cast<float>(model.x());
    d.model_dv[k] = static_cast<float>(model.y());
  }
}

void Processor::fillLoad(status_t& s, bool final, double wall_s) {
  load_.process_cpu_ns = cpuTimeNs(CLOCK_PROCESS_CPUTIME_ID);
  load_.worker_wait_s = odometry_.workerWaitSeconds();
  load_.frames_waited = odometry_.framesWaitedForWorkers();
  const LoadTotals& since = final ? load_at_start_ : load_at_status_;
  const auto ratio = [](double part, double whole) {
    return whole > 0 ? static_cast<float>(part / whole) : 0.0f;
  };
  s.cpu_cores =
      ratio(static_cast<double>(load_.process_cpu_ns - since.process_cpu_ns), 1e9 * wall_s);
  s.processing_cpu_share =
      ratio(static_cast<double>(load_.processing_cpu_ns - since.processing_cpu_ns),
            static_cast<double>(load_.processing_wall_ns - since.processing_wall_ns));
  s.worker_wait_ms = ratio(1e3 * (load_.worker_wait_s - since.worker_wait_s),
                           static_cast<double>(load_.frames - since.frames));
  s.frames_waited_share = ratio(static_cast<double>(load_.frames_waited - since.frames_waited),
                                static_cast<double>(load_.frames - since.frames));
  s.threads = static_cast<std::int16_t>(odometry_.threads());
  s.threads_active = static_cast<std::int16_t>(odometry_.activeThreads());
  const GyroCounters gyro = odometry_.gyroCounters();
  for (int i = 0; i < 3; ++i) s.gyro_bias[i] = static_cast<float>(gyro.bias[i]);
  s.gyro_bias_sigma = static_cast<float>(gyro.bias_sigma);
  load_at_status_ = load_;
}

void Processor::publishStatus(bool final) {
  const auto now = SteadyClock::now();
  status_t& s = *status_;
  s.utime = wallClockMicros();
  s.uptime_us = std::chrono::duration_cast<std::chrono::microseconds>(now - started_).count();
  fillStatus(board_.snapshot(), s);

  // Rates since the last status; the final status gives the averages of the whole run.
  const double dt = std::chrono::duration<double>(now - (final ? started_ : last_status_time_)).count();
  const std::int64_t received = s.frames_received - (final ? 0 : last_status_received_);
  const std::int64_t processed = s.frames_processed - (final ? 0 : last_status_processed_);
  s.receive_rate_hz = dt > 0 ? static_cast<float>(static_cast<double>(received) / dt) : 0.0f;
  s.process_rate_hz = dt > 0 ? static_cast<float>(static_cast<double>(processed) / dt) : 0.0f;
  last_status_time_ = now;
  last_status_received_ = s.frames_received;
  last_status_processed_ = s.frames_processed;

  s.processing_ms_p50 = processing_ms_.percentile(0.50);
  s.processing_ms_p99 = processing_ms_.percentile(0.99);
  s.latency_ms_p50 = latency_ms_.percentile(0.50);
  s.latency_ms_p99 = latency_ms_.percentile(0.99);
  fillLoad(s, final, dt);
  s.last_error_utime = board_.lastError(error_text_.data(), error_text_.size());
  s.last_error.assign(error_text_.data());  // within the reserved capacity: no allocation
  s.final = final ? 1 : 0;

  const int size = s.encode(status_buffer_.data(), 0, static_cast<int>(status_buffer_.size()));
  publish(lcm_.status_channel, status_buffer_, size);
}

}  // namespace omnipose::daemon
