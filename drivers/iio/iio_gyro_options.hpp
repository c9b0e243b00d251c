#pragma once
/// \file iio_gyro_options.hpp
/// What IioGyro (iio_gyro.hpp) is asked to open, and its checks: header-only, so the
/// daemon's configuration checks daemon.yaml's `imu` section with the driver's own rules
/// (src/daemon/config.cpp) without linking the driver.

#include <cstdio>
#include <string>
#include <vector>

namespace omnipose {
namespace iio {

/// A rate as the kernel's sysfs attributes write it ("%.6g": 400, 12.5).
inline std::string formatHz(double hz) {
  char text[32];
  std::snprintf(text, sizeof text, "%.6g", hz);
  return text;
}

}  // namespace iio

struct IioGyroOptions {
  /// `iio:deviceN`, or the device's `name` attribute (e.g. `bmi160`, `lsm6dsx`).
  std::string device;
  /// Where the devices' sysfs directories and character devices are (tests inject others).
  std::string sysfs_root = "/sys/bus/iio/devices";
  std::string dev_root = "/dev";
  /// Hz; 0 = leave the device's rate as it is.
  double sampling_hz = 0.0;
  /// Scans the kernel's buffer holds (buffer/length): 1024 are 1 s at 1 kHz.
  int buffer_length = 1024;

  /// Every problem, each naming the field ("device: ..."); empty when valid. IioGyro::open()
  /// refuses options with problems before it touches a device. A long value is echoed cut
  /// short (its length given).
  std::vector<std::string> validate() const {
    const auto shown = [](const std::string& text) {
      constexpr std::size_t kEchoed = 80;
      return text.size() <= kEchoed
                 ? text
                 : text.substr(0, kEchoed) + "... (" + std::to_string(text.size()) + " bytes)";
    };
    std::vector<std::string> problems;
    if (device.empty())
      problems.push_back("device: needed: iio:deviceN or the device's name (e.g. bmi160)");
    else if (device.find('/') != std::string::npos)
      problems.push_back("device: \"" + shown(device) +
                         "\" is a path: give iio:deviceN or the device's name");
    if (!(sampling_hz >= 0.0 && sampling_hz <= 100000.0))
      problems.push_back("sampling_hz: " + iio::formatHz(sampling_hz) +
                         " is outside [0, 100000] Hz");
    if (buffer_length < 2 || buffer_length > 1 << 20)
      problems.push_back("buffer_length: " + std::to_string(buffer_length) +
                         " is outside [2, 1048576]");
    return problems;
  }
};

}  // namespace omnipose
