#pragma once
/// \file file_io.hpp
/// How omnipose reads and writes files it does not control (configurations, calibrations,
/// lens files, timestamps, trajectories, FFTW wisdom, logs). One place for three rules:
///
/// - **Reading never blocks and never runs away.** A file is opened with O_NONBLOCK (a FIFO
///   without a writer cannot stall start-up), checked on the opened descriptor to be a
///   regular file (FIFOs, sockets, devices such as /dev/zero and directories are refused by
///   name at once) and read whole only up to a bound (kMaxTextFileBytes for text).
/// - **Writing replaces atomically and only what is ours.** A file is written to a
///   temporary file beside its target and renamed over it, so a kill never leaves half a
///   file; a target that is a symbolic link, not a regular file, or a regular file that the
///   writer does not recognise as its own kind is refused and left as it was.
/// - **One writer at a time.** An exclusive lock file (flock) carries the holder's PID; a
///   second process asking for it is refused with that PID; the kernel releases the lock
///   when the holder exits or is killed.
///
/// Every error message starts with the path.

#include <cstdint>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "omnipose/error.hpp"

namespace omnipose {

/// Largest text input read whole: daemon.yaml, calibration.yaml, lens files, motion
/// scripts, timestamps.txt, groundtruth.tum (64 MiB: a timestamps.txt of over a million
/// frames).
inline constexpr std::uintmax_t kMaxTextFileBytes = std::uintmax_t{64} << 20;

/// The bytes of the regular file `path` into `buffer` (resized to the file's size), at most
/// `max_bytes`. Errors: kNotFound (no such file), kInvalidArgument ("not a regular file (a
/// FIFO)" and so on, more than max_bytes, a file that grew while it was read), kIoError.
/// Allocates `buffer` only when it is too small.
Expected<void> readRegularFile(const std::filesystem::path& path, std::uintmax_t max_bytes,
                               std::vector<std::uint8_t>& buffer);

/// Whether `path` is a regular file, checked on a descriptor opened without blocking (for a
/// file another library will open: a FIFO would block it). The errors of readRegularFile.
Expected<void> checkRegularFile(const std::filesystem::path& path);

/// The text of the regular file `path`, at most `max_bytes` (the errors of readRegularFile).
Expected<std::string> readTextFile(const std::filesystem::path& path,
                                   std::uintmax_t max_bytes = kMaxTextFileBytes);

/// readTextFile() that throws std::runtime_error with the error's message.
std::string readTextFileOrThrow(const std::filesystem::path& path,
                                std::uintmax_t max_bytes = kMaxTextFileBytes);

/// Which existing files writeFileAtomically() may replace: an empty regular file, or one
/// whose first bytes `recognise` accepts (`kind` names such a file in the refusal).
struct FileKind {
  const char* kind = "file";
  /// Given up to the first 4 KiB of the existing file; true when it is of this kind.
  bool (*recognise)(std::string_view head) = nullptr;
};

/// The first bytes FFTW writes to a wisdom file: "(fftw-3.3.10 fftwf_wisdom" and the like.
bool looksLikeFftwWisdom(std::string_view head);
/// An LCM event log: it starts with the event sync word 0xEDA1DA01.
bool looksLikeLcmLog(std::string_view head);

/// Whether `path` could be replaced by writeFileAtomically() for `kind` without writing
/// anything: it is missing (and its directory exists) or is a regular file of that kind
/// (or empty), and not a symbolic link. The error says why not.
Expected<void> checkReplaceable(const std::filesystem::path& path, const FileKind& kind);

/// Writes `content` to `path`: checkReplaceable(), then a temporary file in the same
/// directory (created exclusively, mode 0644), flushed to disk, renamed over `path`. On
/// any error the target is unchanged and the temporary file removed.
Expected<void> writeFileAtomically(const std::filesystem::path& path, std::string_view content,
                                   const FileKind& kind);

/// Replaces `path` with a new, empty regular file of this process (created beside it and
/// renamed over it after checkReplaceable()), opened for writing; returns its descriptor
/// (O_CLOEXEC). For logs that are then appended to: the old file is never truncated
/// through a symbolic link or when it is not of `kind`.
Expected<int> createReplacing(const std::filesystem::path& path, const FileKind& kind);

/// An exclusive, advisory lock (flock(2)), released by the destructor and by the kernel when
/// the process ends in any way.
class FileLock {
 public:
  /// Through the lock file `path` (created when missing), which then holds the holder's PID
  /// (when it can be written: the lock holds on a full disk too). Takes the lock or fails
  /// without waiting. kBusy: "PATH: held by process 1234" (the PID read from the file); other
  /// errors name the path (a symbolic link, not a regular file, no permission).
  static Expected<FileLock> acquire(const std::filesystem::path& path);
  /// On the existing file or device node `path` itself (a camera's /dev/video0: nothing is
  /// written). kBusy: "PATH: held by process 1234" (the holder from /proc/locks);
  /// kNotFound when `path` does not exist.
  static Expected<FileLock> acquireOn(const std::filesystem::path& path);

  FileLock() = default;
  FileLock(FileLock&& other) noexcept;
  FileLock& operator=(FileLock&& other) noexcept;
  FileLock(const FileLock&) = delete;
  FileLock& operator=(const FileLock&) = delete;
  ~FileLock();

  bool held() const { return fd_ >= 0; }
  const std::filesystem::path& path() const { return path_; }

 private:
  int fd_ = -1;
  std::filesystem::path path_;
};

}  // namespace omnipose
