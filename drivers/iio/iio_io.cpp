#include "iio/iio_io.hpp"

#include <dirent.h>
#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

namespace omnipose {

SystemIioIo& SystemIioIo::instance() {
  static SystemIioIo io;
  return io;
}

int SystemIioIo::open(const char* path, int flags) { return ::open(path, flags | O_CLOEXEC); }

int SystemIioIo::close(int fd) { return ::close(fd); }

ssize_t SystemIioIo::read(int fd, void* buffer, std::size_t count) {
  return ::read(fd, buffer, count);
}

ssize_t SystemIioIo::write(int fd, const void* buffer, std::size_t count) {
  return ::write(fd, buffer, count);
}

int SystemIioIo::poll(pollfd* fds, nfds_t nfds, int timeout_ms) {
  return ::poll(fds, nfds, timeout_ms);
}

int SystemIioIo::listDirectory(const char* path, std::vector<std::string>& names) {
  names.clear();
  DIR* dir = ::opendir(path);
  if (dir == nullptr) return -1;
  errno = 0;
  while (const dirent* entry = ::readdir(dir)) {
    if (std::strcmp(entry->d_name, ".") != 0 && std::strcmp(entry->d_name, "..") != 0)
      names.emplace_back(entry->d_name);
  }
  const int err = errno;
  ::closedir(dir);
  if (err != 0) {
    errno = err;
    return -1;
  }
  return 0;
}

}  // namespace omnipose
