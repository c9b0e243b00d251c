#include "daemon/instance_lock.hpp"

#include <filesystem>
#include <stdexcept>
#include <string>
#include <system_error>

namespace omnipose::daemon {

FileLock lockSource(const SourceConfig& source) {
  if (source.type != SourceConfig::Type::kV4l2) return {};
  std::error_code ec;
  const std::filesystem::path device = std::filesystem::canonical(source.device, ec);
  if (ec) return {};  // missing: the source's open() says so
  Expected<FileLock> lock = FileLock::acquireOn(device);
  if (lock) return std::move(*lock);
  const std::string what = "source: v4l2 " + source.device;
  if (lock.error().code() == ErrorCode::kBusy)
    throw std::runtime_error(what + " is in use by another omniposed (" +
                             std::string(lock.error().message()) + ")");
  throw std::runtime_error(what + ": cannot take its lock: " + std::string(lock.error().message()));
}

}  // namespace omnipose::daemon
