// daemon.yaml parser: any text either parses (and every bounded number is within its
// documented bound) or throws ConfigError naming the file. Anything else is a defect.
#include <cstdint>
#include <string>

#include "daemon/config.hpp"
#include "omnipose/limits.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  using omnipose::DaemonConfig;
  for (const auto use : {DaemonConfig::Use::kDaemon, DaemonConfig::Use::kReplay}) {
    try {
      const DaemonConfig c = DaemonConfig::parse(text, "fuzz.yaml", "/base", use);
      const auto& r = c.pipeline.registration;
      if (r.window < 16 || r.window > omnipose::WindowRegistration::kMaxWindow || r.step < 1 ||
          r.step > omnipose::WindowRegistration::kMaxStep || c.source.width < 1 ||
          c.source.width > omnipose::limits::kMaxImageSide || c.source.height < 1 ||
          c.source.height > omnipose::limits::kMaxImageSide || !(c.lcm.status_hz > 0) ||
          !(c.lcm.status_hz <= 100) || !(c.source.fps > 0) || !(c.source.fps <= 1000) ||
          !(c.pipeline.fit.huber_delta_px > 0) || !(c.pipeline.fit.huber_delta_px <= 100))
        __builtin_trap();
      (void)c.describe();
    } catch (const omnipose::ConfigError& e) {
      if (e.problems().empty()) __builtin_trap();
      if (std::string(e.what()).find("fuzz.yaml") == std::string::npos) __builtin_trap();
    }
  }
  return 0;
}
