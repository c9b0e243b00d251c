#include "iio/iio_gyro.hpp"

#include <fcntl.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <sstream>

namespace omnipose {
namespace {

constexpr const char* kAxes[] = {"x", "y", "z"};

bool isDeviceId(const std::string& s) {
  constexpr std::string_view kPrefix = "iio:device";
  if (!s.starts_with(kPrefix) || s.size() == kPrefix.size()) return false;
  return std::all_of(s.begin() + static_cast<std::ptrdiff_t>(kPrefix.size()), s.end(),
                     [](char c) { return c >= '0' && c <= '9'; });
}

iio::ChannelRole roleOf(const std::string& prefix) {
  if (prefix == "in_anglvel_x") return iio::ChannelRole::kRateX;
  if (prefix == "in_anglvel_y") return iio::ChannelRole::kRateY;
  if (prefix == "in_anglvel_z") return iio::ChannelRole::kRateZ;
  if (prefix == "in_timestamp") return iio::ChannelRole::kTimestamp;
  return iio::ChannelRole::kOther;
}

}  // namespace

IioGyro::IioGyro(IioGyroOptions options, IioIo& io)
    : options_(std::move(options)), io_(io), label_(options_.device) {}

IioGyro::~IioGyro() { close(); }

Expected<std::string> IioGyro::readFile(const std::string& path, int* err) const {
  const int fd = io_.open(path.c_str(), O_RDONLY);
  if (fd < 0) {
    if (err) *err = errno;
    return fail(ErrorCode::kIoError, "%s: cannot open %s: %s", label_.c_str(), path.c_str(),
                std::strerror(errno));
  }
  char text[256];
  const ssize_t n = io_.read(fd, text, sizeof text - 1);
  const int read_errno = errno;
  io_.close(fd);
  if (n < 0) {
    if (err) *err = read_errno;
    return fail(ErrorCode::kIoError, "%s: cannot read %s: %s", label_.c_str(), path.c_str(),
                std::strerror(read_errno));
  }
  std::string value(text, static_cast<std::size_t>(n));
  while (!value.empty() && (value.back() == '\n' || value.back() == ' ')) value.pop_back();
  if (err) *err = 0;
  return value;
}

Expected<std::string> IioGyro::readAttr(const std::string& relative, int* err) const {
  return readFile(dir_ + "/" + relative, err);
}

int IioGyro::writeAttr(const std::string& relative, const std::string& value) const {
  const std::string path = dir_ + "/" + relative;
  const int fd = io_.open(path.c_str(), O_WRONLY);
  if (fd < 0) return errno;
  const ssize_t n = io_.write(fd, value.data(), value.size());
  const int write_errno = n < 0 ? errno : 0;
  io_.close(fd);
  if (n >= 0 && static_cast<std::size_t>(n) != value.size()) return EIO;
  return write_errno;
}

bool IioGyro::hasAttr(const std::string& relative) const { return readAttr(relative).has_value(); }

std::unexpected<Error> IioGyro::attrError(ErrorCode code, const std::string& relative, int err,
                                          const char* doing) const {
  return fail(code, "%s: %s %s/%s: %s", label_.c_str(), doing, dir_.c_str(), relative.c_str(),
              std::strerror(err));
}

Expected<void> IioGyro::resolveDevice() {
  const std::string& want = options_.device;
  if (isDeviceId(want)) {
    id_ = want;
  } else {
    std::vector<std::string> entries, matches;
    if (io_.listDirectory(options_.sysfs_root.c_str(), entries) < 0)
      return fail(ErrorCode::kNotFound, "iio device \"%s\": cannot list %s: %s", want.c_str(),
                  options_.sysfs_root.c_str(), std::strerror(errno));
    std::sort(entries.begin(), entries.end());
    for (const std::string& e : entries) {
      if (!isDeviceId(e)) continue;
      const auto name = readFile(options_.sysfs_root + "/" + e + "/name");
      if (name && *name == want) matches.push_back(e);
    }
    if (matches.empty())
      return fail(ErrorCode::kNotFound, "iio device \"%s\": no device of that name under %s",
                  want.c_str(), options_.sysfs_root.c_str());
    if (matches.size() > 1)
      return fail(ErrorCode::kInvalidArgument,
                  "iio device \"%s\": %s and %s both have that name; give one as iio:deviceN",
                  want.c_str(), matches[0].c_str(), matches[1].c_str());
    id_ = matches.front();
  }
  dir_ = options_.sysfs_root + "/" + id_;
  int err = 0;
  const auto name = readAttr("name", &err);
  if (!name) {
    label_ = id_;
    return fail(ErrorCode::kNotFound, "iio device %s: not under %s (%s)", id_.c_str(),
                options_.sysfs_root.c_str(), std::strerror(err));
  }
  name_ = *name;
  label_ = id_ + " (" + name_ + ")";
  return {};
}

Expected<void> IioGyro::openCharDevice() {
  const std::string path = options_.dev_root + "/" + id_;
  fd_ = io_.open(path.c_str(), O_RDONLY | O_NONBLOCK);
  if (fd_ >= 0) return {};
  const int err = errno;
  if (err == EBUSY)
    return fail(ErrorCode::kBusy, "%s: %s is in use by another reader (the kernel allows one)",
                label_.c_str(), path.c_str());
  return fail(err == ENOENT ? ErrorCode::kNotFound : ErrorCode::kIoError, "%s: cannot open %s: %s",
              label_.c_str(), path.c_str(), std::strerror(err));
}

Expected<void> IioGyro::takeOverBuffer() {
  const auto enabled = readAttr("buffer/enable");
  if (!enabled) return std::unexpected(enabled.error());
  if (*enabled != "1") return {};
  // Only the holder of /dev/iio:deviceN reads the buffer, and that is us now: the reader that
  // enabled it is gone.
  if (const int err = writeAttr("buffer/enable", "0"); err != 0)
    return attrError(err == EBUSY ? ErrorCode::kBusy : ErrorCode::kIoError, "buffer/enable", err,
                     "cannot disable the buffer another reader left enabled:");
  warnings_.push_back(label_ + ": its buffer was left enabled by a reader that is gone; "
                      "disabled it to configure the scan");
  return {};
}

Expected<void> IioGyro::readChannel(const std::string& prefix, iio::ChannelRole role,
                                    std::vector<iio::ScanChannel>& out) {
  const auto index = readAttr("scan_elements/" + prefix + "_index");
  if (!index) return std::unexpected(index.error());
  const auto type_text = readAttr("scan_elements/" + prefix + "_type");
  if (!type_text) return std::unexpected(type_text.error());
  const auto type = iio::parseScanType(*type_text);
  if (!type)
    return fail(ErrorCode::kUnsupportedFormat, "%s: scan_elements/%s_type: %s", label_.c_str(),
                prefix.c_str(), type.error().c_str());
  const auto i = iio::parseSysfsNumber(*index);
  if (!i || *i < 0 || *i > 4096 || *i != std::floor(*i))
    return fail(ErrorCode::kUnsupportedFormat, "%s: scan_elements/%s_index \"%s\" is not an index",
                label_.c_str(), prefix.c_str(), index->c_str());
  out.push_back({static_cast<int>(*i), *type, role});
  return {};
}

Expected<void> IioGyro::configureChannels() {
  std::vector<std::string> names;
  const std::string dir = dir_ + "/scan_elements";
  if (io_.listDirectory(dir.c_str(), names) < 0)
    return fail(ErrorCode::kUnsupportedFormat, "%s: no buffered interface (%s: %s)",
                label_.c_str(), dir.c_str(), std::strerror(errno));
  std::sort(names.begin(), names.end());
  std::vector<iio::ScanChannel> channels;
  int rate_axes = 0;
  for (const std::string& file : names) {
    if (!file.ends_with("_en")) continue;
    const std::string prefix = file.substr(0, file.size() - 3);
    const iio::ChannelRole role = roleOf(prefix);
    const std::string want = role == iio::ChannelRole::kOther ? "0" : "1";
    if (role != iio::ChannelRole::kOther && role != iio::ChannelRole::kTimestamp) ++rate_axes;
    const auto now = readAttr("scan_elements/" + file);
    if (!now) return std::unexpected(now.error());
    const int err = *now == want ? 0 : writeAttr("scan_elements/" + file, want);
    if (err != 0 && want == "1")
      return attrError(err == EBUSY ? ErrorCode::kBusy : ErrorCode::kIoError,
                       "scan_elements/" + file, err, "cannot enable");
    // A channel that will not be disabled stays in the scan: the layout takes what is enabled.
    if (err != 0) warnings_.push_back(label_ + ": cannot disable scan_elements/" + file + " (" +
                                      std::strerror(err) + "); read along and ignored");
    const auto after = readAttr("scan_elements/" + file);
    if (!after) return std::unexpected(after.error());
    if (*after == "1") {
      if (auto ok = readChannel(prefix, role, channels); !ok) return ok;
    }
  }
  if (rate_axes == 0)
    return fail(ErrorCode::kUnsupportedFormat,
                "%s has no gyro channels (no scan_elements/in_anglvel_{x,y,z}_en): not a gyro?",
                label_.c_str());
  const auto layout = iio::computeLayout(channels);
  if (!layout)
    return fail(ErrorCode::kUnsupportedFormat, "%s: %s", label_.c_str(), layout.error().c_str());
  layout_ = *layout;
  return {};
}

Expected<void> IioGyro::readScale() {
  for (std::size_t k = 0; k < 3; ++k) {
    const std::string axis = std::string("in_anglvel_") + kAxes[k];
    auto scale = readAttr(axis + "_scale");
    std::string used = axis + "_scale";
    if (!scale) {
      scale = readAttr("in_anglvel_scale");
      used = "in_anglvel_scale";
    }
    if (!scale)
      return fail(ErrorCode::kUnsupportedFormat, "%s: neither %s_scale nor in_anglvel_scale: "
                  "cannot convert to rad/s", label_.c_str(), axis.c_str());
    const auto value = iio::parseSysfsNumber(*scale);
    if (!value || *value == 0.0)
      return fail(ErrorCode::kUnsupportedFormat, "%s: %s \"%s\" is not a scale", label_.c_str(),
                  used.c_str(), scale->c_str());
    scale_.scale[k] = *value;
    auto offset = readAttr(axis + "_offset");
    if (!offset) offset = readAttr("in_anglvel_offset");
    const auto o = offset ? iio::parseSysfsNumber(*offset) : Expected<double>(0.0);
    if (!o)
      return fail(ErrorCode::kUnsupportedFormat, "%s: the anglvel offset \"%s\" is not a number",
                  label_.c_str(), offset->c_str());
    scale_.offset[k] = *o;
  }
  return {};
}

Expected<void> IioGyro::setClock() {
  int err = 0;
  const auto clock = readAttr("current_timestamp_clock", &err);
  if (!clock)
    return fail(ErrorCode::kUnsupportedFormat,
                "%s: no current_timestamp_clock (%s; a kernel before 4.10 stamps CLOCK_REALTIME): "
                "its samples cannot be joined with the frames' CLOCK_MONOTONIC", label_.c_str(),
                std::strerror(err));
  clock_ = *clock;
  if (clock_ == "monotonic") return {};
  err = writeAttr("current_timestamp_clock", "monotonic");
  if (const auto now = readAttr("current_timestamp_clock"); now) clock_ = *now;
  if (err != 0 || clock_ != "monotonic")
    return fail(ErrorCode::kUnsupportedFormat,
                "%s: cannot set current_timestamp_clock to monotonic (%s): it stamps on %s, "
                "which cannot be joined with the frames' CLOCK_MONOTONIC", label_.c_str(),
                err != 0 ? std::strerror(err) : "not taken", clock_.c_str());
  return {};
}

Expected<void> IioGyro::setSamplingFrequency() {
  const std::string attr = hasAttr("in_anglvel_sampling_frequency") ? "in_anglvel_sampling_frequency"
                                                                     : "sampling_frequency";
  if (options_.sampling_hz > 0.0) {
    if (const int err = writeAttr(attr, iio::formatHz(options_.sampling_hz)); err != 0) {
      const auto available = readAttr(attr + "_available");
      return fail(ErrorCode::kUnsupportedFormat, "%s: %s %s Hz refused (%s); available: %s",
                  label_.c_str(), attr.c_str(), iio::formatHz(options_.sampling_hz).c_str(),
                  std::strerror(err), available ? available->c_str() : "not listed");
    }
  }
  const auto now = readAttr(attr);
  const auto hz = now ? iio::parseSysfsNumber(*now) : Expected<double>(0.0);
  sampling_hz_ = hz ? *hz : 0.0;
  return {};
}

void IioGyro::setOwnTrigger() {
  const auto current = readAttr("trigger/current_trigger");
  if (!current || !current->empty()) {
    trigger_ = current ? *current : std::string();
    return;
  }
  // A triggered buffer needs a trigger; the device's own data-ready trigger is "NAME-devN".
  const std::string own = name_ + "-dev" + id_.substr(std::string_view("iio:device").size());
  std::vector<std::string> entries;
  if (io_.listDirectory(options_.sysfs_root.c_str(), entries) < 0) return;
  for (const std::string& e : entries) {
    if (!e.starts_with("trigger")) continue;
    const auto name = readFile(options_.sysfs_root + "/" + e + "/name");
    if (name && *name == own && writeAttr("trigger/current_trigger", own) == 0) {
      trigger_ = own;
      return;
    }
  }
}

Expected<void> IioGyro::enableBuffer() {
  if (const int err = writeAttr("buffer/length", std::to_string(options_.buffer_length)); err != 0)
    return attrError(err == EBUSY ? ErrorCode::kBusy : ErrorCode::kIoError, "buffer/length", err,
                     "cannot write");
  const int err = writeAttr("buffer/enable", "1");
  if (err == EBUSY)
    return fail(ErrorCode::kBusy, "%s: buffer/enable: busy (another consumer has the device's "
                "buffer or trigger in use)", label_.c_str());
  if (err == EINVAL)
    return fail(ErrorCode::kUnsupportedFormat, "%s: buffer/enable refused (EINVAL): no trigger "
                "in trigger/current_trigger, or a scan the device cannot deliver", label_.c_str());
  if (err != 0) return attrError(ErrorCode::kIoError, "buffer/enable", err, "cannot write 1 to");
  enabled_by_us_ = true;
  return {};
}

Expected<void> IioGyro::openSteps() {
  if (auto ok = resolveDevice(); !ok) return ok;
  if (auto ok = openCharDevice(); !ok) return ok;
  if (auto ok = takeOverBuffer(); !ok) return ok;
  if (auto ok = configureChannels(); !ok) return ok;
  if (auto ok = readScale(); !ok) return ok;
  if (auto ok = setClock(); !ok) return ok;
  if (auto ok = setSamplingFrequency(); !ok) return ok;
  setOwnTrigger();
  return enableBuffer();
}

Expected<std::string> IioGyro::find() {
  if (auto ok = resolveDevice(); !ok) return std::unexpected(ok.error());
  return label_;
}

Expected<void> IioGyro::open() {
  close();
  warnings_.clear();
  previous_ns_ = 0;
  if (const std::vector<std::string> problems = options_.validate(); !problems.empty()) {
    std::string all;
    for (const std::string& p : problems) all += (all.empty() ? "" : "; ") + p;
    return fail(ErrorCode::kInvalidArgument, "%s: %s", label_.c_str(), all.c_str());
  }
  if (auto ok = openSteps(); !ok) {
    close();
    return ok;
  }
  buffer_.assign(kMaxScansPerRead * layout_.scan_bytes, 0);
  return {};
}

void IioGyro::close() {
  if (enabled_by_us_) writeAttr("buffer/enable", "0");  // fails only when the device is gone
  enabled_by_us_ = false;
  if (fd_ >= 0) io_.close(fd_);
  fd_ = -1;
}

Expected<IioGyro::ReadResult> IioGyro::read(std::span<GyroSample> out, int timeout_ms) {
  if (fd_ < 0) return fail(ErrorCode::kIoError, "%s: read while not open", label_.c_str());
  pollfd p{fd_, POLLIN, 0};
  // Whatever poll says: a device that went away wakes no poller, only a read tells (ENODEV).
  if (io_.poll(&p, 1, timeout_ms) < 0 && errno != EINTR)
    return fail(ErrorCode::kIoError, "%s: poll: %s", label_.c_str(), std::strerror(errno));
  const std::size_t scans = std::min(out.size(), kMaxScansPerRead);
  ReadResult result;
  if (scans == 0) return result;
  const ssize_t n = io_.read(fd_, buffer_.data(), scans * layout_.scan_bytes);
  if (n < 0) {
    const int err = errno;
    if (err == EAGAIN || err == EINTR) return result;
    if (err == ENODEV)
      return fail(ErrorCode::kDisconnected, "%s: the device went away (ENODEV)", label_.c_str());
    return fail(ErrorCode::kIoError, "%s: read: %s", label_.c_str(), std::strerror(err));
  }
  if (n == 0)
    return fail(ErrorCode::kDisconnected, "%s: end of the device's stream", label_.c_str());
  decodeInto(static_cast<std::size_t>(n), out, result);
  return result;
}

void IioGyro::decodeInto(std::size_t bytes, std::span<GyroSample> out, ReadResult& result) {
  const std::size_t whole = bytes / layout_.scan_bytes;
  if (bytes % layout_.scan_bytes != 0) {
    ++result.bad;  // a partial scan: never a whole one's worth of data
    result.last_bad = iio::ScanVerdict::kTruncated;
  }
  for (std::size_t i = 0; i < whole; ++i) {
    const std::span<const std::uint8_t> scan(buffer_.data() + i * layout_.scan_bytes,
                                             layout_.scan_bytes);
    const iio::DecodedScan d = iio::decodeScan(scan, layout_, scale_, previous_ns_);
    if (d.verdict != iio::ScanVerdict::kOk) {
      ++result.bad;
      result.last_bad = d.verdict;
      result.last_bad_timestamp_ns = d.timestamp_ns;
      continue;
    }
    previous_ns_ = d.timestamp_ns;
    out[result.samples++] = d.sample;
  }
}

std::string IioGyro::describe() const {
  if (fd_ < 0) return "iio device " + options_.device;
  std::ostringstream o;
  const iio::ScanType& t = layout_.rate[0].type;
  o << label_ << ", anglvel x,y,z " << (t.big_endian ? "be:" : "le:") << (t.is_signed ? 's' : 'u')
    << t.bits << '/' << t.storage_bits << ">>" << t.shift << " x " << scale_.scale[0]
    << " rad/s, " << layout_.scan_bytes << "-byte scans, clock " << clock_;
  if (sampling_hz_ > 0.0) o << ", " << iio::formatHz(sampling_hz_) << " Hz";
  if (!trigger_.empty()) o << ", trigger " << trigger_;
  return o.str();
}

}  // namespace omnipose
