#pragma once
/// \file fake_iio_device.hpp
/// An IIO device in user space, behind the IioIo seam, that follows the kernel's buffered
/// interface (drivers/iio/industrialio-buffer.c, kfifo buffer; sysfs-bus-iio) strictly
/// enough that a reader passing against it would work on a real BMI160 or LSM6DSx:
///
/// - sysfs: ROOT/iio:deviceN/{name, current_timestamp_clock, in_anglvel_scale, ...,
///   scan_elements/in_*_{en,index,type}, buffer/{enable,length}, trigger/current_trigger},
///   ROOT/triggerK/name. A read gives the value and a newline, then 0 (end of file). A write
///   to a read-only attribute fails at open (EACCES); *_en, buffer/length,
///   current_timestamp_clock and current_trigger give EBUSY while the buffer is enabled; a
///   clock or a sampling frequency the device does not offer, a trigger that does not exist,
///   and enabling with no channel or (for a triggered device) no trigger give EINVAL.
/// - /dev/iio:deviceN: one reader at a time (EBUSY); a read gives whole scans only (as many
///   as fit), EINVAL for a buffer smaller than one scan, EAGAIN when empty (O_NONBLOCK),
///   0 before the buffer was ever enabled (no scan size yet); scans are laid out by the
///   kernel's rule (index order, each aligned to its size, padded to the largest) from the
///   channels enabled at buffer/enable; a full kfifo drops the new scan.
/// - Unplug: the device's files vanish (open ENOENT, reads on open files ENODEV, poll reports
///   nothing, as the kernel's iio_buffer_poll); replug brings it back, possibly at another
///   index, in its power-on state.
///
/// Thread-safe (the daemon's reader thread reads while a test scripts). Waiting in poll()
/// sleeps at most `max_real_wait_ms` of real time. Everything the reader does wrong is
/// recorded in violations(); tests assert it stays empty.

#include <array>
#include <cstdint>
#include <deque>
#include <map>
#include <mutex>
#include <string>
#include <vector>

#include "iio/iio_io.hpp"

namespace omnipose::testing {

struct FakeIioChannel {
  std::string prefix;  ///< "in_anglvel_x"
  int index = 0;       ///< scan index
  std::string type;    ///< "le:s16/16>>0"
  bool enabled = false;  ///< at power-on
};

struct FakeIioConfig {
  std::string sysfs_root = "/fake/sys/bus/iio/devices";
  std::string dev_root = "/fake/dev";
  std::string name = "bmi160";
  int index = 0;
  /// A BMI160 (drivers/iio/imu/bmi160/bmi160_core.c): gyro scan indices 4-6, accel 7-9,
  /// timestamp 10, every axis s16 little-endian. The accel is left enabled, as by an earlier
  /// user.
  std::vector<FakeIioChannel> channels = {
      {"in_anglvel_x", 4, "le:s16/16>>0", false}, {"in_anglvel_y", 5, "le:s16/16>>0", false},
      {"in_anglvel_z", 6, "le:s16/16>>0", false}, {"in_accel_x", 7, "le:s16/16>>0", true},
      {"in_accel_y", 8, "le:s16/16>>0", true},    {"in_accel_z", 9, "le:s16/16>>0", true},
      {"in_timestamp", 10, "le:s64/64>>0", false}};
  /// Further read-only attributes (relative to the device's directory): the BMI160's gyro
  /// scale at ±500 deg/s, as its driver prints it (IIO_VAL_INT_PLUS_MICRO).
  std::map<std::string, std::string> attributes = {{"in_anglvel_scale", "0.000266"},
                                                   {"in_accel_scale", "0.000598"}};
  /// The timestamp clock at power-on; empty: no current_timestamp_clock (Linux < 4.10).
  std::string clock = "realtime";
  /// The clocks a write may choose (the kernel's list); a driver may refuse all but one.
  std::vector<std::string> settable_clocks = {"realtime", "monotonic", "monotonic_raw",
                                              "realtime_coarse", "monotonic_coarse",
                                              "boottime", "tai"};
  /// The sampling frequency attribute, its value and what it takes ("" = none).
  std::string sampling_attribute = "in_anglvel_sampling_frequency";
  std::string sampling_hz = "100";
  std::vector<std::string> sampling_available = {"25", "50", "100", "200", "400", "800",
                                                 "1600", "3200"};
  /// A triggered buffer: enabling needs trigger/current_trigger; the device's own trigger
  /// "NAME-devN" exists as ROOT/triggerK.
  bool needs_trigger = true;
  /// Channels (prefixes) whose `_en` cannot be changed (EINVAL): a scan the reader must take
  /// as it is.
  std::vector<std::string> locked_channels;
  int max_real_wait_ms = 1;
};

class FakeIioDevice final : public IioIo {
 public:
  using Config = FakeIioConfig;
  explicit FakeIioDevice(Config config = {});

  // ---- scripting --------------------------------------------------------------------
  /// The sensor produces a scan: gyro and accel raw values (before the type's shift), the
  /// timestamp in ns. Queued only while the buffer is enabled and not full (else dropped).
  void pushScan(std::int64_t timestamp_ns, std::array<std::int64_t, 3> gyro,
                std::array<std::int64_t, 3> accel = {0, 0, 0});
  /// The next read of the character device gives only `bytes` bytes (a broken driver).
  void shortReadNext(std::size_t bytes);
  /// Another process holds /dev/iio:deviceN open (open EBUSY).
  void setOtherReader(bool other) { other_reader_ = other; }
  /// An in-kernel consumer holds the device (buffer/enable 1 gives EBUSY).
  void setKernelConsumer(bool busy) { kernel_consumer_ = busy; }
  /// A reader that is gone left the buffer enabled with the current channels.
  void leaveBufferEnabled();
  /// The device disappears now / comes back at iio:device<index>, in its power-on state.
  void unplug();
  void replug(int index);
  /// While unplugged, after `listings` more listings of ROOT the device is back at `index`.
  void replugAfterListings(int listings, int index);

  // ---- inspection -------------------------------------------------------------------
  std::vector<std::string> violations() const;
  int openFdCount() const;
  bool bufferEnabled() const;
  bool plugged() const;
  int index() const;
  /// A device attribute's current value (relative to its directory); "" when absent.
  std::string attribute(const std::string& relative) const;
  std::size_t pendingScans() const;
  std::size_t scansDropped() const;
  /// Bytes per scan of the enabled buffer (0 before the first enable).
  std::size_t scanBytes() const;
  int enableCount() const;

  // ---- IioIo ------------------------------------------------------------------------
  int open(const char* path, int flags) override;
  int close(int fd) override;
  ssize_t read(int fd, void* buffer, std::size_t count) override;
  ssize_t write(int fd, const void* buffer, std::size_t count) override;
  int poll(pollfd* fds, nfds_t nfds, int timeout_ms) override;
  int listDirectory(const char* path, std::vector<std::string>& names) override;

 private:
  struct Scan {
    std::int64_t timestamp_ns;
    std::array<std::int64_t, 3> gyro, accel;
  };
  struct Fd {
    bool chrdev = false;
    std::string relative;  ///< attribute path under the device (or "trigger:K/name")
    int flags = 0;
    int generation = 0;
    bool read_done = false;
  };
  struct Placed {
    std::string prefix;
    std::size_t offset;
    int storage_bytes, shift;
    bool big_endian;
  };

  void powerOn(int index);
  std::string deviceDir() const;
  bool isWritable(const std::string& relative) const;
  int fail(int err) const;
  void violation(const std::string& text);
  int writeAttribute(const std::string& relative, std::string value);
  int writeEnable(const std::string& value);
  bool computeLayout();
  void encode(const Scan& scan, std::uint8_t* out) const;
  ssize_t readChrdev(Fd& f, void* buffer, std::size_t count);
  ssize_t readAttribute(Fd& f, void* buffer, std::size_t count);
  int pollLocked(pollfd* fds, nfds_t nfds);

  Config config_;
  mutable std::mutex mutex_;
  bool plugged_ = true;
  int index_ = 0;
  int generation_ = 1;
  std::map<std::string, std::string> attrs_;  ///< the device's, by relative path
  bool enabled_ = false;
  bool ever_enabled_ = false;
  int enable_count_ = 0;
  std::size_t scan_bytes_ = 0;
  std::vector<Placed> placed_;
  std::deque<Scan> fifo_;
  std::size_t dropped_ = 0;
  std::size_t short_read_ = 0;
  bool other_reader_ = false;
  bool kernel_consumer_ = false;
  bool chrdev_open_ = false;
  int replug_after_listings_ = -1;
  int replug_index_ = 0;
  int next_fd_ = 300;
  std::map<int, Fd> fds_;
  std::vector<std::string> violations_;
};

}  // namespace omnipose::testing
