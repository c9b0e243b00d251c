#pragma once
/// \file v4l2_io.hpp
/// The I/O seam of the V4L2 source: every kernel call it makes (open, close, ioctl, poll,
/// mmap, munmap, clock_gettime) goes through a V4l2Io, so that tests can put a fake
/// device behind it that follows the kernel's protocol. The functions mirror the system
/// calls one to one, including their error convention: -1 (MAP_FAILED for mmap) with
/// errno set.
///
/// Sleeping is poll(nullptr, 0, timeout_ms), as with the kernel, so a fake controls time.

#include <cstddef>
#include <ctime>
#include <poll.h>
#include <sys/types.h>

namespace omnipose {

class V4l2Io {
 public:
  virtual ~V4l2Io() = default;

  /// open(2): a file descriptor, or -1 with errno (ENOENT, EBUSY, EACCES, ...).
  virtual int open(const char* path, int flags) = 0;
  /// close(2).
  virtual int close(int fd) = 0;
  /// ioctl(2) with a pointer argument (every VIDIOC_* request takes one).
  virtual int ioctl(int fd, unsigned long request, void* arg) = 0;
  /// poll(2): the number of ready descriptors, 0 on timeout, -1 with errno (EINTR).
  /// nfds == 0 sleeps for timeout_ms.
  virtual int poll(pollfd* fds, nfds_t nfds, int timeout_ms) = 0;
  /// mmap(2): the mapping, or MAP_FAILED with errno.
  virtual void* mmap(void* addr, std::size_t length, int prot, int flags, int fd,
                     off_t offset) = 0;
  /// munmap(2).
  virtual int munmap(void* addr, std::size_t length) = 0;
  /// clock_gettime(2).
  virtual int clockGettime(clockid_t clock, timespec* ts) = 0;
};

/// The real kernel. Stateless; one shared instance serves every source.
class SystemV4l2Io final : public V4l2Io {
 public:
  static SystemV4l2Io& instance();

  int open(const char* path, int flags) override;
  int close(int fd) override;
  int ioctl(int fd, unsigned long request, void* arg) override;
  int poll(pollfd* fds, nfds_t nfds, int timeout_ms) override;
  void* mmap(void* addr, std::size_t length, int prot, int flags, int fd,
             off_t offset) override;
  int munmap(void* addr, std::size_t length) override;
  int clockGettime(clockid_t clock, timespec* ts) override;
};

}  // namespace omnipose
