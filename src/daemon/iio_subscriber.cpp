#include "daemon/iio_subscriber.hpp"

#include <stdexcept>

namespace omnipose::daemon {
namespace {
constexpr int kPollMs = 50;  // how soon stop() is noticed
}  // namespace

IioSubscriber::IioSubscriber(const IioGyroOptions& options, IioIo& io, GyroQueue& queue,
                             StatusBoard& board)
    : io_(io), queue_(queue), board_(board), gyro_(options, io) {
  if (const auto opened = gyro_.open(); !opened)
    throw std::runtime_error(std::string("imu.device: ") + opened.error().c_str());
  for (const std::string& w : gyro_.warnings()) board_.logInfo("imu: warning: %s", w.c_str());
  description_ = "imu: " + gyro_.describe();
}

IioSubscriber::~IioSubscriber() {
  stop();
  gyro_.close();
}

void IioSubscriber::run() {
  while (!stopRequested()) readOnce();
}

void IioSubscriber::readOnce() {
  const auto r = gyro_.read(samples_, kPollMs);
  if (!r) {
    reopen(r.error());
    return;
  }
  if (r->bad > 0) {
    board_.imu_messages_bad += static_cast<std::int64_t>(r->bad);
    board_.reportError("imu: %s: %zu scan(s) skipped (the last: %s, stamped %.6f s)",
                       gyro_.label().c_str(), r->bad, iio::toString(r->last_bad),
                       static_cast<double>(r->last_bad_timestamp_ns) * 1e-9);
  }
  for (std::size_t i = 0; i < r->samples; ++i) {
    if (!queue_.push(samples_[i])) ++board_.imu_samples_dropped;
  }
}

void IioSubscriber::reopen(const Error& why) {
  ++board_.imu_device_lost;
  board_.reportError("imu: %s; closed, looked for again every %lld ms (the images alone "
                     "meanwhile)", why.c_str(), static_cast<long long>(kRetryInterval.count()));
  gyro_.close();
  while (sleepFor(kRetryInterval)) {
    const auto opened = gyro_.open();
    if (opened) {
      for (const std::string& w : gyro_.warnings()) board_.logInfo("imu: warning: %s", w.c_str());
      board_.logInfo("imu: %s is back", gyro_.describe().c_str());
      return;
    }
  }
}

bool IioSubscriber::sleepFor(std::chrono::milliseconds duration) {
  for (auto left = duration; left.count() > 0; left -= std::chrono::milliseconds(kPollMs)) {
    if (stopRequested()) return false;
    io_.poll(nullptr, 0, static_cast<int>(std::min<long long>(left.count(), kPollMs)));
  }
  return !stopRequested();
}

}  // namespace omnipose::daemon
