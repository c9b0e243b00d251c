#include <lcm/lcm-cpp.hpp>
#include <stdexcept>

#include "daemon/message_sink.hpp"

namespace omnipose::daemon {
namespace {

class LcmSink final : public MessageSink {
 public:
  explicit LcmSink(const std::string& url) : url_(url), lcm_(url) {
    if (!lcm_.good()) {
      throw std::runtime_error("lcm.url \"" + url + "\": cannot initialise LCM (bad URL, "
                               "unwritable log file or no multicast route)");
    }
  }

  bool publish(const std::string& channel, const std::uint8_t* data, std::size_t size) override {
    return lcm_.publish(channel, data, static_cast<unsigned int>(size)) == 0;
  }

  std::string describe() const override {
    return "lcm " + (url_.empty() ? std::string("(default udpm)") : url_);
  }

 private:
  std::string url_;
  lcm::LCM lcm_;
};

}  // namespace

std::unique_ptr<MessageSink> makeLcmSink(const std::string& url) {
  return std::make_unique<LcmSink>(url);
}

}  // namespace omnipose::daemon
