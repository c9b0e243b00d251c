#pragma once
/// \file iio_gyro.hpp
/// A gyro read through the Linux IIO buffered interface (kernel
/// Documentation/ABI/testing/sysfs-bus-iio, Documentation/driver-api/iio/buffers.rst): the
/// device's sysfs attributes configure the scan, /dev/iio:deviceN delivers it.
///
/// open(), in this order (every failure an Error naming the device, "iio:device0 (bmi160)"):
///  1. the device: `iio:deviceN` as given, or the one whose `name` attribute is the given name
///     (looked up again at every open(): the index may change when the device comes back);
///  2. /dev/iio:deviceN opened O_RDONLY | O_NONBLOCK: the kernel lets one reader hold it
///     (EBUSY: "in use by another reader"); holding it, a buffer found enabled was left so
///     by a reader that is gone, and is disabled (a warning);
///  3. scan_elements: in_anglvel_{x,y,z}_en and in_timestamp_en set, every other `*_en`
///     cleared (one the driver will not clear stays, with a warning); the layout computed
///     from the channels that read back enabled (iio_scan.hpp);
///  4. the scale to rad/s: in_anglvel_{x,y,z}_scale or in_anglvel_scale, and _offset if any;
///  5. current_timestamp_clock set to `monotonic` (CLOCK_MONOTONIC, the frames' clock): a
///     device whose clock cannot be made monotonic (no such attribute before Linux 4.10, whose
///     stamps are CLOCK_REALTIME) is refused, since its samples would never meet the frames;
///  6. the sampling frequency when asked for (in_anglvel_sampling_frequency or
///     sampling_frequency; the driver's nearest rate is read back);
///  7. trigger/current_trigger, when empty, set to the device's own trigger
///     ("NAME-devN") if there is one;
///  8. buffer/length, then buffer/enable.
/// close() disables the buffer it enabled and closes the device; what else open() set (the
/// channels, the clock, the rate, the trigger) stays as it is: nothing is restored.
///
/// read() polls and reads whole scans (never a part of one) and decodes them: t is the
/// scan's timestamp in seconds on CLOCK_MONOTONIC, the rate in rad/s about the sensor's axes.
/// A scan with a timestamp of zero or not after the previous one, a rate at the type's rail
/// (saturated) or a partial read is counted as bad and skipped. The device going away
/// (ENODEV, or the end of the file) is ErrorCode::kDisconnected: the caller closes and
/// re-opens (the daemon every 0.5 s); this class never retries on its own.
///
/// Threads: one thread uses an IioGyro at a time. Realtime: open() allocates; read()
/// allocates nothing.

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include "iio/iio_gyro_options.hpp"
#include "iio/iio_io.hpp"
#include "iio/iio_scan.hpp"
#include "omnipose/error.hpp"
#include "omnipose/gyro.hpp"

namespace omnipose {

class IioGyro {
 public:
  /// Scans read by one read() at most.
  static constexpr std::size_t kMaxScansPerRead = 64;

  /// What one read() gave.
  struct ReadResult {
    std::size_t samples = 0;  ///< good samples written to the output, oldest first
    std::size_t bad = 0;      ///< scans skipped (partial, timestamp zero or back, saturated)
    iio::ScanVerdict last_bad = iio::ScanVerdict::kOk;  ///< why the last bad one was
    std::int64_t last_bad_timestamp_ns = 0;             ///< and its timestamp
  };

  /// `io` is borrowed and must outlive this.
  explicit IioGyro(IioGyroOptions options, IioIo& io = SystemIioIo::instance());
  /// close().
  ~IioGyro();
  IioGyro(const IioGyro&) = delete;
  IioGyro& operator=(const IioGyro&) = delete;

  /// Finds, configures and starts the device (steps above). Errors: kNotFound (no such
  /// device, or none of that name), kBusy (another reader holds it or its buffer),
  /// kUnsupportedFormat (no gyro channels or timestamp, a clock that cannot be monotonic, a
  /// scan layout not supported), kIoError (an attribute that cannot be read or written).
  /// On failure nothing stays open and a buffer it enabled is disabled again.
  Expected<void> open();
  /// Step 1 of open() alone (`omniposed --check`): the device found under the sysfs root, its
  /// label ("iio:device0 (bmi160)") returned; nothing is opened or written. Errors as open()'s
  /// kNotFound and kInvalidArgument (two devices of that name).
  Expected<std::string> find();
  /// Disables the buffer it enabled and closes the device (idempotent; never fails: a device
  /// that is gone has nothing left to disable).
  void close();
  bool isOpen() const { return fd_ >= 0; }

  /// Waits up to `timeout_ms` for scans, reads up to min(out.size(), kMaxScansPerRead) and
  /// writes the good ones to `out`. Errors: kDisconnected (ENODEV or end of file: close and
  /// open again), kIoError (any other failure, named). Nothing ready is 0 samples.
  Expected<ReadResult> read(std::span<GyroSample> out, int timeout_ms);

  /// "iio:device0 (bmi160), anglvel x,y,z le:s16/16>>0 x 0.000266 rad/s, 16-byte scans,
  /// clock monotonic, 200 Hz" (after open()); the configured device before.
  std::string describe() const;
  /// What open() changed or found that the user should know (a buffer left enabled, a
  /// channel that would not be disabled).
  const std::vector<std::string>& warnings() const { return warnings_; }
  /// "iio:device0 (bmi160)": the device as messages name it (the configured one before
  /// open()).
  const std::string& label() const { return label_; }

 private:
  Expected<void> resolveDevice();
  Expected<void> openCharDevice();
  Expected<void> takeOverBuffer();
  Expected<void> configureChannels();
  Expected<void> readChannel(const std::string& prefix, iio::ChannelRole role,
                             std::vector<iio::ScanChannel>& out);
  Expected<void> readScale();
  Expected<void> setClock();
  Expected<void> setSamplingFrequency();
  void setOwnTrigger();
  Expected<void> enableBuffer();
  Expected<void> openSteps();
  void decodeInto(std::size_t bytes, std::span<GyroSample> out, ReadResult& result);

  /// The sysfs file `path` without its trailing newline; `err` (when given) gets the errno
  /// (ENOENT: no such attribute), 0 on success.
  Expected<std::string> readFile(const std::string& path, int* err = nullptr) const;
  /// readFile() of the attribute `relative` to the device's directory.
  Expected<std::string> readAttr(const std::string& relative, int* err = nullptr) const;
  /// 0, or the errno of open/write.
  int writeAttr(const std::string& relative, const std::string& value) const;
  bool hasAttr(const std::string& relative) const;
  std::unexpected<Error> attrError(ErrorCode code, const std::string& relative, int err,
                                   const char* doing) const;

  IioGyroOptions options_;
  IioIo& io_;
  int fd_ = -1;
  std::string id_;      ///< iio:deviceN
  std::string name_;    ///< its name attribute
  std::string dir_;     ///< sysfs_root/iio:deviceN
  std::string label_;
  iio::ScanLayout layout_;
  iio::RateScale scale_;
  std::string clock_;
  double sampling_hz_ = 0.0;  ///< as read back; 0 unknown
  std::string trigger_;
  bool enabled_by_us_ = false;
  std::int64_t previous_ns_ = 0;
  std::vector<std::uint8_t> buffer_;
  std::vector<std::string> warnings_;
};

}  // namespace omnipose
