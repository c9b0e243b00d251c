#pragma once
/// \file iio_io.hpp
/// The I/O seam of the IIO gyro: every kernel call it makes on sysfs attributes and on the
/// character device /dev/iio:deviceN (open, close, read, write, poll) and the listing of a
/// sysfs directory go through an IioIo, so that tests can put a fake device behind it that
/// follows the kernel's protocol. The calls mirror the system calls one to one, including
/// their error convention: -1 with errno set.
///
/// Sleeping is poll(nullptr, 0, timeout_ms), as with the kernel, so a fake controls time.

#include <poll.h>
#include <sys/types.h>

#include <cstddef>
#include <string>
#include <vector>

namespace omnipose {

class IioIo {
 public:
  virtual ~IioIo() = default;

  /// open(2): a file descriptor, or -1 with errno (ENOENT, EBUSY, EACCES, ...).
  virtual int open(const char* path, int flags) = 0;
  /// close(2).
  virtual int close(int fd) = 0;
  /// read(2): bytes read, 0 at the end, -1 with errno (EAGAIN, EINVAL, ENODEV, ...).
  virtual ssize_t read(int fd, void* buffer, std::size_t count) = 0;
  /// write(2): bytes written, -1 with errno (EBUSY, EINVAL, ...).
  virtual ssize_t write(int fd, const void* buffer, std::size_t count) = 0;
  /// poll(2): the number of ready descriptors, 0 on timeout, -1 with errno (EINTR).
  /// nfds == 0 sleeps for timeout_ms.
  virtual int poll(pollfd* fds, nfds_t nfds, int timeout_ms) = 0;
  /// The names in directory `path` ("." and ".." left out), or -1 with errno (ENOENT, ...).
  /// Allocates: start-up and re-opening only.
  virtual int listDirectory(const char* path, std::vector<std::string>& names) = 0;
};

/// The real kernel. Stateless; one shared instance serves every reader.
class SystemIioIo final : public IioIo {
 public:
  static SystemIioIo& instance();

  int open(const char* path, int flags) override;
  int close(int fd) override;
  ssize_t read(int fd, void* buffer, std::size_t count) override;
  ssize_t write(int fd, const void* buffer, std::size_t count) override;
  int poll(pollfd* fds, nfds_t nfds, int timeout_ms) override;
  int listDirectory(const char* path, std::vector<std::string>& names) override;
};

}  // namespace omnipose
