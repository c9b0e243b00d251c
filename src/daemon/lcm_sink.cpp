#include <fcntl.h>
#include <lcm/eventlog.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <lcm/lcm-cpp.hpp>
#include <stdexcept>

#include "daemon/message_sink.hpp"
#include "daemon/wall_clock.hpp"

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

/// `file://PATH?mode=w`: the LCM event log written with LCM's own eventlog
/// writer, but checked. LCM 1.3.1's file provider ignores the result of every write, so a
/// full or failing disk would go unnoticed; here every write is checked (the stream is
/// unbuffered: the error shows at the message that failed), a failed write returns false
/// with the reason in lastError(), and the partial record is cut off again (truncated to
/// the end of the last whole record), so the log stays readable and writing resumes when
/// there is room again.
class FileLogSink final : public MessageSink {
 public:
  FileLogSink(const std::string& url, const std::string& path, const char* mode)
      : url_(url), path_(path) {
    errno = 0;
    log_ = lcm_eventlog_create(path.c_str(), mode);
    if (log_ == nullptr) {
      const int e = errno;
      throw std::runtime_error("lcm.url \"" + url + "\": cannot open the log file " + path +
                               " for writing" + (e != 0 ? std::string(": ") + std::strerror(e) : ""));
    }
    std::setvbuf(log_->f, nullptr, _IONBF, 0);
    good_end_ = ftello(log_->f);
    if (good_end_ < 0) good_end_ = 0;
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
  lcm_eventlog_t* log_ = nullptr;
  off_t good_end_ = 0;
  char error_[512] = {};
};

/// For `file://PATH?mode=w` (nothing else in the query): the path and the mode; else false.
bool parseWritableLogUrl(const std::string& url, std::string& path, const char*& mode) {
  constexpr std::string_view kScheme = "file://";
  if (url.rfind(kScheme, 0) != 0) return false;
  const std::string rest = url.substr(kScheme.size());
  const auto q = rest.find('?');
  if (q == std::string::npos) return false;  // LCM's default for file:// is read mode
  const std::string query = rest.substr(q + 1);
  if (query != "mode=w") return false;  // anything else is LCM's own file provider
  mode = "w";
  path = rest.substr(0, q);
  return !path.empty();
}

}  // namespace

std::unique_ptr<MessageSink> makeLcmSink(const std::string& url) {
  std::string path;
  const char* mode = nullptr;
  if (parseWritableLogUrl(url, path, mode)) return std::make_unique<FileLogSink>(url, path, mode);
  return std::make_unique<LcmSink>(url);
}

}  // namespace omnipose::daemon
