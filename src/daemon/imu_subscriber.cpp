#include "daemon/imu_subscriber.hpp"

#include <lcm/lcm.h>

#include <cstdint>
#include <span>
#include <stdexcept>

#include "daemon/imu_message.hpp"

namespace omnipose::daemon {

ImuSubscriber::ImuSubscriber(const std::string& url, const std::string& channel,
                             GyroQueue& queue, StatusBoard& board)
    : url_(url), channel_(channel), queue_(queue), board_(board) {
  lcm_ = lcm_create(url_.empty() ? nullptr : url_.c_str());
  if (lcm_ == nullptr) {
    throw std::runtime_error("imu.url \"" + url_ + "\": cannot initialise LCM (bad URL, "
                             "unreadable log file or no multicast route)");
  }
  subscription_ = lcm_subscribe(lcm_, channel_.c_str(), &ImuSubscriber::onMessage, this);
  if (subscription_ == nullptr) {
    lcm_destroy(lcm_);
    throw std::runtime_error("imu.channel \"" + channel_ + "\": cannot subscribe on " +
                             (url_.empty() ? std::string("LCM's default URL") : url_));
  }
}

ImuSubscriber::~ImuSubscriber() {
  stop();
  lcm_unsubscribe(lcm_, subscription_);
  lcm_destroy(lcm_);
}

std::string ImuSubscriber::describe() const {
  return "imu: omnipose.imu_t on channel " + channel_ + " of lcm " +
         (url_.empty() ? std::string("(default udpm)") : url_);
}

void ImuSubscriber::run() {
  constexpr int kTimeoutMs = 50;  // how soon stop() is noticed
  while (!stopRequested()) {
    if (lcm_handle_timeout(lcm_, kTimeoutMs) < 0) {
      ended_.store(true);
      board_.reportError("imu: the stream on channel %s of %s ended; going on from the images "
                         "alone", channel_.c_str(), url_.empty() ? "LCM" : url_.c_str());
      return;
    }
  }
}

void ImuSubscriber::onMessage(const lcm_recv_buf_t* buffer, const char*, void* self) {
  static_cast<ImuSubscriber*>(self)->receive(buffer->data, static_cast<int>(buffer->data_size));
}

void ImuSubscriber::receive(const void* data, int size) {
  const auto* bytes = static_cast<const std::uint8_t*>(data);
  const Expected<GyroSample> sample =
      decodeImuMessage(std::span<const std::uint8_t>(bytes, size > 0 ? static_cast<std::size_t>(size) : 0));
  if (!sample) {
    ++board_.imu_messages_bad;
    board_.reportError("%s, on channel %s", sample.error().c_str(), channel_.c_str());
    return;
  }
  if (!queue_.push(*sample)) ++board_.imu_samples_dropped;
}

}  // namespace omnipose::daemon
