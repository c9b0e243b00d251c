#include "fake_iio_device.hpp"

#include <fcntl.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <thread>

namespace omnipose::testing {

FakeIioDevice::FakeIioDevice(Config config) : config_(std::move(config)) { powerOn(config_.index); }

void FakeIioDevice::powerOn(int index) {
  index_ = index;
  attrs_.clear();
  attrs_["name"] = config_.name;
  if (!config_.clock.empty()) attrs_["current_timestamp_clock"] = config_.clock;
  for (const auto& [k, v] : config_.attributes) attrs_[k] = v;
  if (!config_.sampling_attribute.empty()) {
    attrs_[config_.sampling_attribute] = config_.sampling_hz;
    std::string list;
    for (const auto& f : config_.sampling_available) list += (list.empty() ? "" : " ") + f;
    attrs_[config_.sampling_attribute + "_available"] = list;
  }
  for (const auto& c : config_.channels) {
    attrs_["scan_elements/" + c.prefix + "_en"] = c.enabled ? "1" : "0";
    attrs_["scan_elements/" + c.prefix + "_index"] = std::to_string(c.index);
    attrs_["scan_elements/" + c.prefix + "_type"] = c.type;
  }
  attrs_["buffer/enable"] = "0";
  attrs_["buffer/length"] = "2";
  if (config_.needs_trigger) attrs_["trigger/current_trigger"] = "";
  enabled_ = ever_enabled_ = false;
  scan_bytes_ = 0;
  placed_.clear();
  fifo_.clear();
}

std::string FakeIioDevice::deviceDir() const {
  return config_.sysfs_root + "/iio:device" + std::to_string(index_);
}

int FakeIioDevice::fail(int err) const {
  errno = err;
  return -1;
}

void FakeIioDevice::violation(const std::string& text) { violations_.push_back(text); }

bool FakeIioDevice::isWritable(const std::string& r) const {
  return r == "current_timestamp_clock" || r == config_.sampling_attribute ||
         r == "buffer/enable" || r == "buffer/length" || r == "trigger/current_trigger" ||
         (r.starts_with("scan_elements/") && r.ends_with("_en"));
}

// ---- scripting ------------------------------------------------------------------------

void FakeIioDevice::pushScan(std::int64_t timestamp_ns, std::array<std::int64_t, 3> gyro,
                             std::array<std::int64_t, 3> accel) {
  std::lock_guard lock(mutex_);
  const std::size_t length = std::stoul(attrs_["buffer/length"]);
  if (!plugged_ || !enabled_ || fifo_.size() >= length) {
    ++dropped_;
    return;
  }
  fifo_.push_back({timestamp_ns, gyro, accel});
}

void FakeIioDevice::shortReadNext(std::size_t bytes) {
  std::lock_guard lock(mutex_);
  short_read_ = bytes;
}

void FakeIioDevice::leaveBufferEnabled() {
  std::lock_guard lock(mutex_);
  if (!computeLayout()) return;
  enabled_ = ever_enabled_ = true;
  attrs_["buffer/enable"] = "1";
}

void FakeIioDevice::unplug() {
  std::lock_guard lock(mutex_);
  plugged_ = false;
  ++generation_;
  chrdev_open_ = false;  // the old fd is dead; the node is gone
  fifo_.clear();
}

void FakeIioDevice::replug(int index) {
  std::lock_guard lock(mutex_);
  plugged_ = true;
  powerOn(index);
}

void FakeIioDevice::replugAfterListings(int listings, int index) {
  std::lock_guard lock(mutex_);
  replug_after_listings_ = listings;
  replug_index_ = index;
}

// ---- inspection -----------------------------------------------------------------------

std::vector<std::string> FakeIioDevice::violations() const {
  std::lock_guard lock(mutex_);
  return violations_;
}
int FakeIioDevice::openFdCount() const {
  std::lock_guard lock(mutex_);
  return static_cast<int>(fds_.size());
}
bool FakeIioDevice::bufferEnabled() const {
  std::lock_guard lock(mutex_);
  return plugged_ && enabled_;
}
bool FakeIioDevice::plugged() const {
  std::lock_guard lock(mutex_);
  return plugged_;
}
int FakeIioDevice::index() const {
  std::lock_guard lock(mutex_);
  return index_;
}
std::string FakeIioDevice::attribute(const std::string& relative) const {
  std::lock_guard lock(mutex_);
  const auto it = attrs_.find(relative);
  return it == attrs_.end() ? std::string() : it->second;
}
std::size_t FakeIioDevice::pendingScans() const {
  std::lock_guard lock(mutex_);
  return fifo_.size();
}
std::size_t FakeIioDevice::scansDropped() const {
  std::lock_guard lock(mutex_);
  return dropped_;
}
std::size_t FakeIioDevice::scanBytes() const {
  std::lock_guard lock(mutex_);
  return scan_bytes_;
}
int FakeIioDevice::enableCount() const {
  std::lock_guard lock(mutex_);
  return enable_count_;
}

// ---- the kernel's scan layout (written apart from the reader's, to check it) ------------

bool FakeIioDevice::computeLayout() {
  struct Ch {
    int index;
    std::string prefix, type;
  };
  std::vector<Ch> on;
  for (const auto& c : config_.channels)
    if (attrs_["scan_elements/" + c.prefix + "_en"] == "1") on.push_back({c.index, c.prefix, c.type});
  if (on.empty()) return false;
  std::sort(on.begin(), on.end(), [](const Ch& a, const Ch& b) { return a.index < b.index; });
  placed_.clear();
  std::size_t bytes = 0, largest = 1;
  for (const Ch& c : on) {
    char endian[3] = {};
    char sign = 0;
    int bits = 0, storage = 0, shift = 0;
    std::sscanf(c.type.c_str(), "%2[a-z]:%c%d/%d>>%d", endian, &sign, &bits, &storage, &shift);
    const std::size_t size = static_cast<std::size_t>(storage / 8);
    if (bytes % size != 0) bytes += size - bytes % size;
    placed_.push_back({c.prefix, bytes, storage / 8, shift, std::strcmp(endian, "be") == 0});
    bytes += size;
    largest = std::max(largest, size);
  }
  if (bytes % largest != 0) bytes += largest - bytes % largest;
  scan_bytes_ = bytes;
  return true;
}

void FakeIioDevice::encode(const Scan& scan, std::uint8_t* out) const {
  std::memset(out, 0xA5, scan_bytes_);  // padding is not zero in the kernel either
  for (const Placed& p : placed_) {
    std::int64_t value = 0;
    if (p.prefix == "in_timestamp") value = scan.timestamp_ns;
    static const char* kAxes[] = {"x", "y", "z"};
    for (int k = 0; k < 3; ++k) {
      if (p.prefix == std::string("in_anglvel_") + kAxes[k]) value = scan.gyro[k];
      if (p.prefix == std::string("in_accel_") + kAxes[k]) value = scan.accel[k];
    }
    const std::uint64_t word = static_cast<std::uint64_t>(value) << p.shift;
    for (int i = 0; i < p.storage_bytes; ++i) {
      const int at = p.big_endian ? p.storage_bytes - 1 - i : i;
      out[p.offset + static_cast<std::size_t>(at)] = static_cast<std::uint8_t>(word >> (8 * i));
    }
  }
}

// ---- IioIo ------------------------------------------------------------------------------

int FakeIioDevice::open(const char* path_c, int flags) {
  std::lock_guard lock(mutex_);
  const std::string path(path_c);
  const std::string dir = deviceDir() + "/";
  Fd f;
  f.flags = flags;
  f.generation = generation_;
  if (plugged_ && path == config_.dev_root + "/iio:device" + std::to_string(index_)) {
    if ((flags & O_ACCMODE) != O_RDONLY) violation("the character device opened for writing");
    if (other_reader_ || chrdev_open_) return fail(EBUSY);
    chrdev_open_ = true;
    f.chrdev = true;
  } else if (plugged_ && config_.needs_trigger && path == config_.sysfs_root + "/trigger0/name") {
    if ((flags & O_ACCMODE) != O_RDONLY) return fail(EACCES);
    f.relative = "trigger:name";
  } else if (plugged_ && path.starts_with(dir) && attrs_.count(path.substr(dir.size()))) {
    f.relative = path.substr(dir.size());
    if ((flags & O_ACCMODE) != O_RDONLY && !isWritable(f.relative)) {
      violation("opened read-only attribute " + f.relative + " for writing");
      return fail(EACCES);
    }
  } else {
    return fail(ENOENT);
  }
  const int fd = next_fd_++;
  fds_[fd] = f;
  return fd;
}

int FakeIioDevice::close(int fd) {
  std::lock_guard lock(mutex_);
  const auto it = fds_.find(fd);
  if (it == fds_.end()) {
    violation("close of unknown fd " + std::to_string(fd));
    return fail(EBADF);
  }
  // The kernel does not disable the buffer on release: the reader must.
  if (it->second.chrdev && it->second.generation == generation_) chrdev_open_ = false;
  fds_.erase(it);
  return 0;
}

ssize_t FakeIioDevice::read(int fd, void* buffer, std::size_t count) {
  std::lock_guard lock(mutex_);
  const auto it = fds_.find(fd);
  if (it == fds_.end()) {
    violation("read of unknown fd " + std::to_string(fd));
    return fail(EBADF);
  }
  if (it->second.generation != generation_ || !plugged_) return fail(ENODEV);
  return it->second.chrdev ? readChrdev(it->second, buffer, count)
                           : readAttribute(it->second, buffer, count);
}

ssize_t FakeIioDevice::readAttribute(Fd& f, void* buffer, std::size_t count) {
  if ((f.flags & O_ACCMODE) == O_WRONLY) return fail(EBADF);
  if (f.read_done) return 0;
  const std::string value =
      (f.relative == "trigger:name" ? config_.name + "-dev" + std::to_string(index_)
                                    : attrs_[f.relative]) + "\n";
  const std::size_t n = std::min(count, value.size());
  std::memcpy(buffer, value.data(), n);
  f.read_done = true;
  return static_cast<ssize_t>(n);
}

ssize_t FakeIioDevice::readChrdev(Fd& f, void* buffer, std::size_t count) {
  if (!ever_enabled_) {
    violation("read of the character device before the buffer was ever enabled");
    return 0;  // no scan size yet: the kernel returns 0
  }
  if (count < scan_bytes_) {
    violation("read of " + std::to_string(count) + " bytes, less than a scan of " +
              std::to_string(scan_bytes_));
    return fail(EINVAL);
  }
  if (fifo_.empty()) {
    if (!(f.flags & O_NONBLOCK)) violation("a blocking read with nothing to read");
    return fail(EAGAIN);
  }
  auto* out = static_cast<std::uint8_t*>(buffer);
  const std::size_t scans = std::min(count / scan_bytes_, fifo_.size());
  std::vector<std::uint8_t> bytes(scans * scan_bytes_);
  for (std::size_t i = 0; i < scans; ++i) encode(fifo_[i], bytes.data() + i * scan_bytes_);
  fifo_.erase(fifo_.begin(), fifo_.begin() + static_cast<std::ptrdiff_t>(scans));
  std::size_t n = bytes.size();
  if (short_read_ > 0) {
    n = std::min(n, short_read_);
    short_read_ = 0;
  }
  std::memcpy(out, bytes.data(), n);
  return static_cast<ssize_t>(n);
}

ssize_t FakeIioDevice::write(int fd, const void* buffer, std::size_t count) {
  std::lock_guard lock(mutex_);
  const auto it = fds_.find(fd);
  if (it == fds_.end()) {
    violation("write of unknown fd " + std::to_string(fd));
    return fail(EBADF);
  }
  if (it->second.generation != generation_ || !plugged_) return fail(ENODEV);
  if (it->second.chrdev || (it->second.flags & O_ACCMODE) == O_RDONLY) return fail(EBADF);
  std::string value(static_cast<const char*>(buffer), count);
  while (!value.empty() && value.back() == '\n') value.pop_back();
  const int err = writeAttribute(it->second.relative, value);
  if (err != 0) return fail(err);
  return static_cast<ssize_t>(count);
}

int FakeIioDevice::writeAttribute(const std::string& r, std::string value) {
  if (r == "buffer/enable") return writeEnable(value);
  if (enabled_) {
    violation("wrote " + r + " while the buffer is enabled");
    return EBUSY;
  }
  if (r == "current_timestamp_clock") {
    if (std::find(config_.settable_clocks.begin(), config_.settable_clocks.end(), value) ==
        config_.settable_clocks.end())
      return EINVAL;
  } else if (r == config_.sampling_attribute) {
    if (std::find(config_.sampling_available.begin(), config_.sampling_available.end(), value) ==
        config_.sampling_available.end())
      return EINVAL;
  } else if (r == "buffer/length") {
    if (value.empty() || value.find_first_not_of("0123456789") != std::string::npos ||
        std::stoul(value) == 0)
      return EINVAL;
  } else if (r == "trigger/current_trigger") {
    if (!value.empty() && value != config_.name + "-dev" + std::to_string(index_)) return EINVAL;
  } else if (value != "0" && value != "1") {  // *_en
    return EINVAL;
  } else if (std::any_of(config_.locked_channels.begin(), config_.locked_channels.end(),
                         [&](const std::string& c) { return r == "scan_elements/" + c + "_en"; })) {
    return attrs_[r] == value ? 0 : EINVAL;
  }
  attrs_[r] = value;
  return 0;
}

int FakeIioDevice::writeEnable(const std::string& value) {
  if (value != "0" && value != "1") return EINVAL;
  const bool want = value == "1";
  if (want == enabled_) return 0;  // the kernel: nothing to change
  if (want) {
    if (kernel_consumer_) return EBUSY;
    if (config_.needs_trigger && attrs_["trigger/current_trigger"].empty()) return EINVAL;
    if (!computeLayout()) return EINVAL;
    ever_enabled_ = true;
    ++enable_count_;
  } else {
    fifo_.clear();
  }
  enabled_ = want;
  attrs_["buffer/enable"] = value;
  return 0;
}

int FakeIioDevice::pollLocked(pollfd* fds, nfds_t nfds) {
  int ready = 0;
  for (nfds_t i = 0; i < nfds; ++i) {
    fds[i].revents = 0;
    const auto it = fds_.find(fds[i].fd);
    if (it == fds_.end()) {
      fds[i].revents = POLLNVAL;
    } else if (it->second.chrdev && it->second.generation == generation_ && plugged_ &&
               enabled_ && !fifo_.empty()) {
      fds[i].revents = static_cast<short>(fds[i].events & (POLLIN | POLLRDNORM));
    }
    if (fds[i].revents != 0) ++ready;
  }
  return ready;
}

int FakeIioDevice::poll(pollfd* fds, nfds_t nfds, int timeout_ms) {
  {
    std::lock_guard lock(mutex_);
    if (const int ready = pollLocked(fds, nfds); ready > 0) return ready;
  }
  const int wait = std::min(timeout_ms < 0 ? config_.max_real_wait_ms : timeout_ms,
                            config_.max_real_wait_ms);
  std::this_thread::sleep_for(std::chrono::milliseconds(wait));
  std::lock_guard lock(mutex_);
  return pollLocked(fds, nfds);
}

int FakeIioDevice::listDirectory(const char* path_c, std::vector<std::string>& names) {
  std::lock_guard lock(mutex_);
  names.clear();
  const std::string path(path_c);
  if (path == config_.sysfs_root) {
    if (!plugged_ && replug_after_listings_ >= 0 && replug_after_listings_-- == 0) {
      plugged_ = true;
      powerOn(replug_index_);
    }
    if (plugged_) names.push_back("iio:device" + std::to_string(index_));
    if (plugged_ && config_.needs_trigger) names.push_back("trigger0");
    return 0;
  }
  const std::string dir = deviceDir();
  if (!plugged_ || !(path == dir || path.starts_with(dir + "/"))) return fail(ENOENT);
  const std::string prefix = path == dir ? "" : path.substr(dir.size() + 1) + "/";
  for (const auto& [relative, value] : attrs_) {
    if (!relative.starts_with(prefix)) continue;
    const std::string rest = relative.substr(prefix.size());
    const std::string first = rest.substr(0, rest.find('/'));
    if (std::find(names.begin(), names.end(), first) == names.end()) names.push_back(first);
  }
  return names.empty() ? fail(ENOENT) : 0;
}

}  // namespace omnipose::testing
