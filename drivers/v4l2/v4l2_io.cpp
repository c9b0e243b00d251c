#include "v4l2/v4l2_io.hpp"

#include <fcntl.h>
#include <sys/ioctl.h>
#include <sys/mman.h>
#include <unistd.h>

namespace omnipose {

SystemV4l2Io& SystemV4l2Io::instance() {
  static SystemV4l2Io io;
  return io;
}

int SystemV4l2Io::open(const char* path, int flags) { return ::open(path, flags); }

int SystemV4l2Io::close(int fd) { return ::close(fd); }

int SystemV4l2Io::ioctl(int fd, unsigned long request, void* arg) {
  return ::ioctl(fd, request, arg);
}

int SystemV4l2Io::poll(pollfd* fds, nfds_t nfds, int timeout_ms) {
  return ::poll(fds, nfds, timeout_ms);
}

void* SystemV4l2Io::mmap(void* addr, std::size_t length, int prot, int flags, int fd,
                         off_t offset) {
  return ::mmap(addr, length, prot, flags, fd, offset);
}

int SystemV4l2Io::munmap(void* addr, std::size_t length) { return ::munmap(addr, length); }

int SystemV4l2Io::clockGettime(clockid_t clock, timespec* ts) {
  return ::clock_gettime(clock, ts);
}

}  // namespace omnipose
