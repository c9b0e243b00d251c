#pragma once
/// \file shared_lcm_sink.hpp
/// A daemon message sink that publishes into an lcm::LCM the test owns: with memq:// the
/// test's subscribers share that one instance, and nothing leaves the process.

#include <lcm/lcm-cpp.hpp>

#include <cstddef>
#include <cstdint>
#include <string>

#include "daemon/message_sink.hpp"

namespace omnipose::testing {

class SharedLcmSink final : public daemon::MessageSink {
 public:
  explicit SharedLcmSink(lcm::LCM& lcm) : lcm_(lcm) {}
  bool publish(const std::string& channel, const std::uint8_t* data, std::size_t size) override {
    return lcm_.publish(channel, data, static_cast<unsigned int>(size)) == 0;
  }
  std::string describe() const override { return "shared lcm (test)"; }

 private:
  lcm::LCM& lcm_;
};

}  // namespace omnipose::testing
