#include "daemon/daemon.hpp"

#include <opencv2/core/utility.hpp>
#include <stdexcept>

#include "daemon/iio_subscriber.hpp"
#include "daemon/imu_subscriber.hpp"
#include "daemon/instance_lock.hpp"
#include "daemon/source_factory.hpp"

namespace omnipose::daemon {
Daemon::Daemon(const DaemonConfig& config, std::FILE* log, std::unique_ptr<FrameSource> source,
               std::unique_ptr<MessageSink> sink, DaemonOptions options)
    : config_(config), options_(options), log_(log), board_(log) {
  const auto phase = [&](const char* what) {
    if (options_.phase != nullptr) options_.phase->store(what);
  };
  cv::setNumThreads(1);

  phase("loading the calibration");
  const Calibration calibration = Calibration::load(config_.calibration);
  // Before anything is sized by the pair (frame buffers, window spectra).
  if (const auto problems = config_.checkAgainst(
          calibration, config_.origin.empty() ? "daemon.yaml" : config_.origin); !problems.empty()) {
    std::string what = "configuration does not fit the calibration:";
    for (const auto& p : problems) what += "\n  " + p;
    throw ConfigError(what, problems);
  }
  const cv::Size frame_size = inputFrameSize(calibration, config_.pipeline.unwrap.input);

  phase("locking the camera");
  source_lock_ = lockSource(config_.source);
  source_ = source ? std::move(source)
                   : makeFrameSource(config_.source, {frame_size, config_.calibration,
                                                     calibration.sensor});
  phase("opening the LCM output");
  sink_ = sink ? std::move(sink) : makeLcmSink(config_.lcm.url);
  phase("opening the gyro");
  imu_ = makeGyroStream();

  const bool lossless = options_.force_lossless ||
                        (config_.source.type == SourceConfig::Type::kFile && !config_.source.realtime);
  mailbox_ = std::make_unique<FrameMailbox>(frame_size, lossless, 3, &board_.frames_skipped_stale);

  phase("opening the source");
  if (auto opened = source_->open(); !opened) {
    throw std::runtime_error(std::string("source: ") + opened.error().c_str());
  }
  if (source_->frameSize() != frame_size) {
    throw std::runtime_error("source: " + source_->describe() + " delivers " +
                             std::to_string(source_->frameSize().width) + "x" +
                             std::to_string(source_->frameSize().height) +
                             " frames, the calibration (" + config_.calibration.string() +
                             ", input " +
                             (config_.pipeline.unwrap.input == InputKind::kOmni ? "omni" : "panorama") +
                             ") expects " + std::to_string(frame_size.width) + "x" +
                             std::to_string(frame_size.height));
  }
  source_description_ = source_->describe();
  source_warnings_ = source_->warnings();
  phase(config_.map_file.path.empty() ? "building the pipeline (FFT plans)"
                                      : "building the pipeline (FFT plans), loading the map");
  processor_ = std::make_unique<Processor>(calibration, config_.odometry(), config_.lcm, *sink_,
                                           board_, source_description_, gyro_queue_.get(),
                                           config_.map_file);
  capture_ = std::make_unique<CaptureLoop>(*source_, *mailbox_, board_, options_.capture);
}

std::unique_ptr<GyroStream> Daemon::makeGyroStream() {
  if (config_.imu.source == ImuConfig::Source::kNone) return nullptr;
  // The calibration's imu section is there: checkAgainst() refused start-up without it.
  gyro_queue_ = std::make_unique<GyroQueue>();
  if (config_.imu.source == ImuConfig::Source::kLcm) {
    return std::make_unique<ImuSubscriber>(
        config_.imu.url.empty() ? config_.lcm.url : config_.imu.url, config_.imu.channel,
        *gyro_queue_, board_);
  }
  IioGyroOptions o;
  o.device = config_.imu.device;
  o.sampling_hz = config_.imu.sampling_hz;
  if (!options_.iio_sysfs_root.empty()) o.sysfs_root = options_.iio_sysfs_root;
  if (!options_.iio_dev_root.empty()) o.dev_root = options_.iio_dev_root;
  IioIo& io = options_.iio_io != nullptr ? *options_.iio_io : SystemIioIo::instance();
  return std::make_unique<IioSubscriber>(o, io, *gyro_queue_, board_);
}

Daemon::~Daemon() {
  requestStop();
  join();
}

void Daemon::start() {
  if (started_) return;
  started_ = true;
  if (imu_) imu_->start();
  capture_thread_ = std::thread([this] { capture_->run(); });
  process_thread_ = std::thread([this] { processLoop(); });
}

void Daemon::requestStop() {
  if (mailbox_) mailbox_->requestStop();
}

bool Daemon::finished() const {
  std::lock_guard lock(done_mutex_);
  return processing_done_;
}

bool Daemon::waitFinished(std::chrono::milliseconds timeout) {
  std::unique_lock lock(done_mutex_);
  return done_cv_.wait_for(lock, timeout, [&] { return processing_done_; });
}

void Daemon::join() {
  if (!started_ || joined_) return;
  joined_ = true;
  if (process_thread_.joinable()) process_thread_.join();
  // The processor ends only after the capture thread closed the mailbox or on stop.
  mailbox_->requestStop();
  if (capture_thread_.joinable()) capture_thread_.join();
  if (imu_) imu_->stop();
  processor_->finish();
  processor_->publishStatus(true);
}

DaemonStats Daemon::stats() const { return board_.snapshot(); }

void Daemon::processLoop() {
  const auto period = std::chrono::duration_cast<SteadyClock::duration>(
      std::chrono::duration<double>(1.0 / config_.lcm.status_hz));
  constexpr auto kMaxWait = std::chrono::milliseconds(200);  // heartbeat cadence
  auto next_status = SteadyClock::now() + period;
  MailboxFrame frame;
  for (;;) {
    board_.beatProcessor();
    const auto deadline = std::min(next_status, SteadyClock::now() + kMaxWait);
    const auto taken = mailbox_->take(deadline, frame);
    if (taken == FrameMailbox::TakeResult::kFrame) {
      processor_->handleFrame(frame);
      mailbox_->release();
    }
    const auto now = SteadyClock::now();
    if (now >= next_status) {
      processor_->publishStatus(false);
      next_status += period;
      if (next_status <= now) next_status = now + period;  // fell behind: no burst
    }
    if (taken == FrameMailbox::TakeResult::kClosed) break;
  }
  board_.markProcessorFinished();
  {
    std::lock_guard lock(done_mutex_);
    processing_done_ = true;
  }
  done_cv_.notify_all();
}

}  // namespace omnipose::daemon
