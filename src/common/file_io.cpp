#include "omnipose/file_io.hpp"

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <sys/sysmacros.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <stdexcept>

namespace omnipose {
namespace fs = std::filesystem;
namespace {

constexpr std::size_t kHeadBytes = 4096;

/// "a FIFO", "a directory", ... for a file that is not regular.
const char* typeName(mode_t mode) {
  if (S_ISDIR(mode)) return "a directory";
  if (S_ISFIFO(mode)) return "a FIFO";
  if (S_ISSOCK(mode)) return "a socket";
  if (S_ISCHR(mode)) return "a character device";
  if (S_ISBLK(mode)) return "a block device";
  if (S_ISLNK(mode)) return "a symbolic link";
  return "a special file";
}

/// Closes a descriptor on scope exit.
struct Fd {
  int fd = -1;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

Error openError(const fs::path& path, int e) {
  if (e == ENOENT || e == ENOTDIR)
    return Error::format(ErrorCode::kNotFound, "%s: no such file", path.c_str());
  if (e == ELOOP)
    return Error::format(ErrorCode::kInvalidArgument, "%s: is a symbolic link (not followed)",
                         path.c_str());
  if (e == ENXIO)  // a socket, or a FIFO opened for writing without a reader
    return Error::format(ErrorCode::kInvalidArgument, "%s: not a regular file", path.c_str());
  return Error::format(ErrorCode::kIoError, "%s: cannot open: %s", path.c_str(), std::strerror(e));
}

/// Opens `path` for reading without blocking and checks that it is a regular file.
Expected<int> openRegularForReading(const fs::path& path, bool follow_links, struct stat& st) {
  const int flags = O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY | (follow_links ? 0 : O_NOFOLLOW);
  const int fd = ::open(path.c_str(), flags);
  if (fd < 0) return std::unexpected(openError(path, errno));
  if (::fstat(fd, &st) != 0) {
    const int e = errno;
    ::close(fd);
    return fail(ErrorCode::kIoError, "%s: cannot stat: %s", path.c_str(), std::strerror(e));
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    return fail(ErrorCode::kInvalidArgument, "%s: not a regular file (%s)", path.c_str(),
                typeName(st.st_mode));
  }
  return fd;
}

/// Reads up to `limit` bytes from `fd` into `out` (resized to what was read).
Expected<void> readUpTo(int fd, const fs::path& path, std::size_t limit,
                        std::vector<std::uint8_t>& out) {
  out.resize(limit);
  std::size_t got = 0;
  while (got < limit) {
    const ssize_t n = ::read(fd, out.data() + got, limit - got);
    if (n == 0) break;
    if (n < 0) {
      if (errno == EINTR) continue;
      return fail(ErrorCode::kIoError, "%s: read failed: %s", path.c_str(), std::strerror(errno));
    }
    got += static_cast<std::size_t>(n);
  }
  out.resize(got);
  return {};
}

Expected<void> checkDirectory(const fs::path& path) {
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  struct stat st {};
  if (::stat(dir.c_str(), &st) != 0 || !S_ISDIR(st.st_mode))
    return fail(ErrorCode::kNotFound, "%s: its directory %s does not exist", path.c_str(),
                dir.c_str());
  return {};
}

/// Creates an exclusive temporary file beside `path`; its name in `tmp`.
Expected<int> createTemporaryBeside(const fs::path& path, std::string& tmp) {
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  tmp = (dir / ("." + path.filename().string() + ".tmp.XXXXXX")).string();
  const int fd = ::mkostemp(tmp.data(), O_CLOEXEC);
  if (fd < 0)
    return fail(ErrorCode::kIoError, "%s: cannot create a temporary file beside it: %s",
                path.c_str(), std::strerror(errno));
  ::fchmod(fd, 0644);
  return fd;
}

Expected<void> renameOver(const std::string& tmp, const fs::path& path) {
  if (::rename(tmp.c_str(), path.c_str()) != 0) {
    const int e = errno;
    ::unlink(tmp.c_str());
    return fail(ErrorCode::kIoError, "%s: cannot replace it: %s", path.c_str(), std::strerror(e));
  }
  // The rename itself on disk (best effort: a directory that cannot be opened still renamed).
  const fs::path dir = path.has_parent_path() ? path.parent_path() : fs::path(".");
  const int dfd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    ::fsync(dfd);
    ::close(dfd);
  }
  return {};
}

}  // namespace

Expected<void> readRegularFile(const fs::path& path, std::uintmax_t max_bytes,
                               std::vector<std::uint8_t>& buffer) {
  struct stat st {};
  const Expected<int> opened = openRegularForReading(path, true, st);
  if (!opened) return std::unexpected(opened.error());
  const Fd fd{*opened};
  const auto size = static_cast<std::uintmax_t>(st.st_size);
  if (size > max_bytes)
    return fail(ErrorCode::kInvalidArgument, "%s: %ju bytes, more than the %ju allowed", path.c_str(),
                size, max_bytes);
  // One byte more than the size the file had: a file that grew meanwhile is noticed.
  if (auto r = readUpTo(fd.fd, path, static_cast<std::size_t>(size) + 1, buffer); !r) return r;
  if (buffer.size() > size)
    return fail(ErrorCode::kInvalidArgument, "%s: changed while being read", path.c_str());
  return {};
}

Expected<void> checkRegularFile(const fs::path& path) {
  struct stat st {};
  const Expected<int> opened = openRegularForReading(path, true, st);
  if (!opened) return std::unexpected(opened.error());
  ::close(*opened);
  return {};
}

Expected<std::string> readTextFile(const fs::path& path, std::uintmax_t max_bytes) {
  std::vector<std::uint8_t> bytes;
  if (auto r = readRegularFile(path, max_bytes, bytes); !r) return std::unexpected(r.error());
  return std::string(bytes.begin(), bytes.end());
}

std::string readTextFileOrThrow(const fs::path& path, std::uintmax_t max_bytes) {
  Expected<std::string> text = readTextFile(path, max_bytes);
  if (!text) throw std::runtime_error(text.error().c_str());
  return std::move(*text);
}

bool looksLikeFftwWisdom(std::string_view head) {
  // "(fftw-3.3.10 fftwf_wisdom #x..." (FFTW's export format, any version and precision).
  const auto start = head.find_first_not_of(" \t\r\n");
  if (start == std::string_view::npos) return false;
  head.remove_prefix(start);
  if (!head.starts_with("(fftw-")) return false;
  const auto space = head.find(' ');
  return space != std::string_view::npos && head.substr(space + 1).starts_with("fftw") &&
         head.substr(space + 1, 32).find("wisdom") != std::string_view::npos;
}

bool looksLikeLcmLog(std::string_view head) {
  constexpr unsigned char kSync[4] = {0xED, 0xA1, 0xDA, 0x01};
  return head.size() >= 4 &&
         std::equal(kSync, kSync + 4, reinterpret_cast<const unsigned char*>(head.data()));
}

Expected<void> checkReplaceable(const fs::path& path, const FileKind& kind) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return checkDirectory(path);
    return fail(ErrorCode::kIoError, "%s: cannot stat: %s", path.c_str(), std::strerror(errno));
  }
  if (S_ISLNK(st.st_mode))
    return fail(ErrorCode::kInvalidArgument,
                "%s: is a symbolic link; not written through it (give the link's target)",
                path.c_str());
  if (!S_ISREG(st.st_mode))
    return fail(ErrorCode::kInvalidArgument, "%s: not a regular file (%s); not written",
                path.c_str(), typeName(st.st_mode));
  if (st.st_size == 0) return {};
  struct stat opened_st {};
  const Expected<int> opened = openRegularForReading(path, false, opened_st);
  if (!opened) return std::unexpected(opened.error());
  const Fd fd{*opened};
  std::vector<std::uint8_t> head;
  if (auto r = readUpTo(fd.fd, path, kHeadBytes, head); !r) return r;
  const std::string_view text(reinterpret_cast<const char*>(head.data()), head.size());
  if (kind.recognise == nullptr || !kind.recognise(text))
    return fail(ErrorCode::kInvalidArgument, "%s: exists and is not %s; not replaced", path.c_str(),
                kind.kind);
  return {};
}

Expected<void> writeFileAtomically(const fs::path& path, std::string_view content,
                                   const FileKind& kind) {
  if (auto ok = checkReplaceable(path, kind); !ok) return ok;
  std::string tmp;
  const Expected<int> created = createTemporaryBeside(path, tmp);
  if (!created) return std::unexpected(created.error());
  const int fd = *created;
  std::size_t written = 0;
  int error = 0;
  while (written < content.size()) {
    const ssize_t n = ::write(fd, content.data() + written, content.size() - written);
    if (n < 0) {
      if (errno == EINTR) continue;
      error = errno;
      break;
    }
    written += static_cast<std::size_t>(n);
  }
  if (error == 0 && ::fsync(fd) != 0) error = errno;
  if (::close(fd) != 0 && error == 0) error = errno;
  if (error != 0) {
    ::unlink(tmp.c_str());
    return fail(ErrorCode::kIoError, "%s: write failed: %s", path.c_str(), std::strerror(error));
  }
  return renameOver(tmp, path);
}

Expected<int> createReplacing(const fs::path& path, const FileKind& kind) {
  if (auto ok = checkReplaceable(path, kind); !ok) return std::unexpected(ok.error());
  std::string tmp;
  const Expected<int> created = createTemporaryBeside(path, tmp);
  if (!created) return created;
  if (auto renamed = renameOver(tmp, path); !renamed) {
    ::close(*created);
    return std::unexpected(renamed.error());
  }
  return created;
}

Expected<FileLock> FileLock::acquire(const fs::path& path) {
  const int fd = ::open(path.c_str(), O_RDWR | O_CREAT | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC | O_NOCTTY,
                        0644);
  if (fd < 0) {
    const int e = errno;
    if (e == ENOENT) return std::unexpected(checkDirectory(path).error());
    return std::unexpected(openError(path, e));
  }
  Fd guard{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0 || !S_ISREG(st.st_mode))
    return fail(ErrorCode::kInvalidArgument, "%s: lock file is not a regular file (%s)", path.c_str(),
                typeName(st.st_mode));
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int e = errno;
    if (e != EWOULDBLOCK)
      return fail(ErrorCode::kIoError, "%s: cannot lock: %s", path.c_str(), std::strerror(e));
    std::vector<std::uint8_t> text;
    long pid = 0;
    if (readUpTo(fd, path, 32, text)) {
      const std::string s(text.begin(), text.end());
      pid = std::strtol(s.c_str(), nullptr, 10);
    }
    if (pid > 0) return fail(ErrorCode::kBusy, "%s: held by process %ld", path.c_str(), pid);
    return fail(ErrorCode::kBusy, "%s: held by another process", path.c_str());
  }
  // The PID for the refusal of a second holder; the lock holds without it (a full disk).
  const std::string pid = std::to_string(::getpid()) + "\n";
  if (::ftruncate(fd, 0) == 0) (void)!::pwrite(fd, pid.data(), pid.size(), 0);
  FileLock lock;
  lock.fd_ = fd;
  lock.path_ = path;
  guard.fd = -1;
  return lock;
}

namespace {

/// The PID holding a flock on the file of `fd`, from /proc/locks ("1: FLOCK  ADVISORY  WRITE
/// 1234 00:05:123 0 EOF": the device's major and minor in hex, then the inode); 0 unknown.
long flockHolder(int fd) {
  struct stat st {};
  if (::fstat(fd, &st) != 0) return 0;
  char id[64];
  std::snprintf(id, sizeof(id), "%02x:%02x:%lu", major(st.st_dev), minor(st.st_dev),
                static_cast<unsigned long>(st.st_ino));
  // A /proc file reports size 0: read as a stream, up to a bound.
  const Fd locks{::open("/proc/locks", O_RDONLY | O_CLOEXEC)};
  std::vector<std::uint8_t> bytes;
  if (locks.fd < 0 || !readUpTo(locks.fd, "/proc/locks", std::size_t{1} << 20, bytes)) return 0;
  const std::string text(bytes.begin(), bytes.end());
  std::size_t start = 0;
  while (start < text.size()) {
    const std::size_t end = std::min(text.find('\n', start), text.size());
    const std::string line = text.substr(start, end - start);
    start = end + 1;
    if (line.find("FLOCK") == std::string::npos || line.find(" -> ") != std::string::npos) continue;
    const std::size_t at = line.find(std::string(" ") + id + " ");
    if (at == std::string::npos) continue;
    const std::size_t pid_start = line.rfind(' ', at - 1);
    if (pid_start != std::string::npos)
      return std::strtol(line.c_str() + pid_start + 1, nullptr, 10);
  }
  return 0;
}

}  // namespace

Expected<FileLock> FileLock::acquireOn(const fs::path& path) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC | O_NOCTTY);
  if (fd < 0) return std::unexpected(openError(path, errno));
  Fd guard{fd};
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int e = errno;
    if (e != EWOULDBLOCK)
      return fail(ErrorCode::kIoError, "%s: cannot lock: %s", path.c_str(), std::strerror(e));
    if (const long pid = flockHolder(fd); pid > 0)
      return fail(ErrorCode::kBusy, "%s: held by process %ld", path.c_str(), pid);
    return fail(ErrorCode::kBusy, "%s: held by another process", path.c_str());
  }
  FileLock lock;
  lock.fd_ = fd;
  lock.path_ = path;
  guard.fd = -1;
  return lock;
}

FileLock::FileLock(FileLock&& other) noexcept : fd_(other.fd_), path_(std::move(other.path_)) {
  other.fd_ = -1;
}

FileLock& FileLock::operator=(FileLock&& other) noexcept {
  if (this != &other) {
    if (fd_ >= 0) ::close(fd_);
    fd_ = other.fd_;
    path_ = std::move(other.path_);
    other.fd_ = -1;
  }
  return *this;
}

FileLock::~FileLock() {
  if (fd_ >= 0) ::close(fd_);  // releases the flock; the file stays (removing it would race)
}

}  // namespace omnipose
