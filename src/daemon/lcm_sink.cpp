#include <fcntl.h>
#include <sys/stat.h>
#include <lcm/eventlog.h>
#include <unistd.h>

#include <cerrno>
#include <cstdlib>
#include <new>
#include <optional>
#include <cstdio>
#include <cstring>
#include <lcm/lcm-cpp.hpp>
#include <stdexcept>

#include "daemon/message_sink.hpp"
#include "daemon/wall_clock.hpp"
#include "omnipose/file_io.hpp"

namespace omnipose::daemon {
namespace {

constexpr FileKind kLcmLogKind{"an LCM log", looksLikeLcmLog};

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

/// `file://PATH?mode=w`: the LCM event log written with LCM's own eventlog
/// writer, but checked. LCM 1.3.1's file provider ignores the result of every write, so a
/// full or failing disk would go unnoticed; here every write is checked (the stream is
/// unbuffered: the error shows at the message that failed), a failed write returns false
/// with the reason in lastError(), and the partial record is cut off again (truncated to
/// the end of the last whole record), so the log stays readable and writing resumes when
/// there is room again.
class FileLogSink final : public MessageSink {
 public:
  FileLogSink(const std::string& url, const std::string& path) : url_(url), path_(path) {
    const std::string where = "lcm.url \"" + url + "\": ";
    if (Expected<void> ok = checkReplaceable(path, kLcmLogKind); !ok)
      throw std::runtime_error(where + std::string(ok.error().message()));
    // One writer per log: a second daemon with the same configuration is refused here,
    // before it replaces the first one's log.
    Expected<FileLock> lock = FileLock::acquire(path + ".lock");
    if (!lock) {
      throw std::runtime_error(where + (lock.error().code() == ErrorCode::kBusy
                                            ? "the log is in use by another omniposed: "
                                            : "cannot lock the log: ") +
                               std::string(lock.error().message()));
    }
    lock_ = std::move(*lock);
    // A new file renamed over the old log: never written through a symbolic link, never
    // over a file that is not an LCM log, never a FIFO or a device.
    const Expected<int> fd = createReplacing(path, kLcmLogKind);
    if (!fd)
      throw std::runtime_error(where + "cannot create the log: " + std::string(fd.error().message()));
    std::FILE* file = ::fdopen(*fd, "w");
    if (file == nullptr) {
      ::close(*fd);
      throw std::runtime_error(where + "cannot open the log file " + path);
    }
    // lcm_eventlog_create() would fopen() the path itself; the struct is LCM's public one
    // and lcm_eventlog_destroy() fcloses and frees it.
    log_ = static_cast<lcm_eventlog_t*>(std::calloc(1, sizeof(lcm_eventlog_t)));
    if (log_ == nullptr) {
      std::fclose(file);
      throw std::bad_alloc();
    }
    log_->f = file;
    std::setvbuf(log_->f, nullptr, _IONBF, 0);
    good_end_ = 0;
  }
  ~FileLogSink() override { lcm_eventlog_destroy(log_); }
  FileLogSink(const FileLogSink&) = delete;
  FileLogSink& operator=(const FileLogSink&) = delete;

  bool publish(const std::string& channel, const std::uint8_t* data, std::size_t size) override {
    lcm_eventlog_event_t event{};
    event.timestamp = wallClockMicros();
    event.channellen = static_cast<std::int32_t>(channel.size());
    event.datalen = static_cast<std::int32_t>(size);
    event.channel = const_cast<char*>(channel.c_str());
    event.data = const_cast<std::uint8_t*>(data);
    errno = 0;
    if (lcm_eventlog_write_event(log_, &event) == 0) {
      const off_t end = ftello(log_->f);
      if (end >= 0) good_end_ = end;
      return true;
    }
    const int e = errno != 0 ? errno : EIO;
    std::snprintf(error_, sizeof(error_), "LCM log %s: %s", path_.c_str(), std::strerror(e));
    // Cut the partial record off so that the log stays a sequence of whole records.
    std::clearerr(log_->f);
    if (ftruncate(fileno(log_->f), good_end_) == 0) fseeko(log_->f, good_end_, SEEK_SET);
    return false;
  }

  const char* lastError() const override { return error_; }

  std::string describe() const override { return "lcm log " + url_; }

 private:
  std::string url_;
  std::string path_;
  FileLock lock_;
  lcm_eventlog_t* log_ = nullptr;
  off_t good_end_ = 0;
  char error_[512] = {};
};

}  // namespace

namespace {

/// The path of any `file://PATH[?...]` URL; nullopt for other URLs.
std::optional<std::string> filePathOf(const std::string& url) {
  constexpr std::string_view kScheme = "file://";
  if (url.rfind(kScheme, 0) != 0) return std::nullopt;
  std::string path = url.substr(kScheme.size());
  path = path.substr(0, path.find('?'));
  if (path.empty()) return std::nullopt;
  return path;
}

/// LCM's own file provider (a file:// URL that is not ours) would fopen() the path, which
/// blocks on a FIFO without a peer: anything there that is not a regular file is refused.
void refuseSpecialFile(const std::string& url) {
  const std::optional<std::string> path = filePathOf(url);
  struct stat st {};
  if (path && ::stat(path->c_str(), &st) == 0 && !S_ISREG(st.st_mode))
    throw std::runtime_error("lcm.url \"" + url + "\": " + *path + ": not a regular file");
}

}  // namespace

std::optional<std::string> writableLogPath(const std::string& url) {
  const auto q = url.find('?');
  // Without a query LCM's file provider reads; any other query is LCM's own provider.
  if (q == std::string::npos || url.substr(q + 1) != "mode=w") return std::nullopt;
  return filePathOf(url);
}

std::optional<std::string> logProblem(const std::string& url) {
  const std::optional<std::string> path = writableLogPath(url);
  if (!path) return std::nullopt;
  if (Expected<void> ok = checkReplaceable(*path, kLcmLogKind); !ok)
    return "lcm.url \"" + url + "\": " + std::string(ok.error().message());
  return std::nullopt;
}

std::unique_ptr<MessageSink> makeLcmSink(const std::string& url) {
  if (const std::optional<std::string> path = writableLogPath(url))
    return std::make_unique<FileLogSink>(url, *path);
  refuseSpecialFile(url);
  return std::make_unique<LcmSink>(url);
}

}  // namespace omnipose::daemon
