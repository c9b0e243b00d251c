// imu.csv, a dataset's recorded gyro (omnipose::parseGyroCsv): either std::runtime_error
// names the input, or every sample is finite with strictly increasing times and the timing
// figures agree with them. The input is the file's text.
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <string_view>

#include "omnipose/io/gyro.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  try {
    const omnipose::GyroRecording r = omnipose::parseGyroCsv(text, "imu.csv");
    if (r.samples.empty()) __builtin_trap();
    for (std::size_t k = 0; k < r.samples.size(); ++k) {
      const omnipose::GyroSample& s = r.samples[k];
      if (!std::isfinite(s.t) || !s.rate.allFinite()) __builtin_trap();
      if (k > 0 && !(s.t > r.samples[k - 1].t)) __builtin_trap();
    }
    if (!(r.median_interval_s >= 0.0) || !(r.longest_gap_s >= r.median_interval_s)) __builtin_trap();
    if (r.gaps < 0 || static_cast<std::size_t>(r.gaps) >= r.samples.size()) __builtin_trap();
  } catch (const std::runtime_error& e) {
    if (std::string_view(e.what()).substr(0, 7) != "imu.csv") __builtin_trap();
  }
  return 0;
}
