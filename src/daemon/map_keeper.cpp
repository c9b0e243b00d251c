#include "daemon/map_keeper.hpp"

#include <chrono>
#include <fstream>
#include <string>
#include <system_error>

namespace omnipose::daemon {
namespace {

/// Whether the file at `path` starts like an omnipose map (a damaged map rather than
/// someone else's file).
bool startsLikeAMap(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::string head(64, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(std::max<std::streamsize>(in.gcount(), 0)));
  return map::looksLikeMapFile(head);
}

}  // namespace

MapKeeper::MapKeeper(const MapFileConfig& config, int max_places, StatusBoard& board)
    : config_(config),
      board_(board),
      max_places_(max_places),
      next_save_(SteadyClock::now() +
                 std::chrono::duration_cast<SteadyClock::duration>(
                     std::chrono::duration<double>(config.save_interval_s))),
      saver_([this] { saverLoop(); }) {}

MapKeeper::~MapKeeper() {
  {
    std::lock_guard lock(mutex_);
    stop_ = true;
  }
  wake_.notify_all();
  if (saver_.joinable()) saver_.join();
}

void MapKeeper::load(Odometry& odometry, const Calibration& calibration) {
  const std::string path = config_.path.string();
  const Expected<void> loaded = map::loadMap(config_.path, calibration, max_places_, snapshot_);
  if (loaded) {
    if (const Expected<void> restored = odometry.restoreMap(snapshot_); restored) {
      board_.logInfo("map %s: %d places loaded; finding where the robot is in it", path.c_str(),
                     snapshot_.place_count);
    } else {
      board_.reportError("map %s refused (%s); %s; starting with an empty map", path.c_str(),
                         restored.error().c_str(), keepAside(".refused").c_str());
    }
  } else if (loaded.error().code() == ErrorCode::kNotFound) {
    board_.logInfo("map %s: none yet; starting with an empty map", path.c_str());
  } else if (std::error_code ec; std::filesystem::is_regular_file(config_.path, ec) &&
                                 startsLikeAMap(config_.path)) {
    // A damaged map: kept for a look, and a new one saved in its place.
    board_.reportError("map %s refused (%s); %s; starting with an empty map", path.c_str(),
                       loaded.error().c_str(), keepAside(".refused").c_str());
  } else {
    foreign_ = true;
    board_.reportError("map %s refused (%s); it is not an omnipose map and is left alone: "
                       "the map will not be saved",
                       path.c_str(), loaded.error().c_str());
  }
  // Room for the largest map, before the first frame.
  odometry.snapshotMap(snapshot_);
}

std::string MapKeeper::keepAside(const char* suffix) const {
  const std::filesystem::path aside = config_.path.string() + suffix;
  std::error_code ec;
  std::filesystem::rename(config_.path, aside, ec);
  return ec ? "could not keep it aside: " + ec.message() : "kept as " + aside.string();
}

void MapKeeper::afterFrame(const Odometry& odometry, const OdometryResult& result,
                           std::uint64_t sequence, SteadyClock::time_point now) {
  if (relocalising_ && !result.relocalising) {
    if (result.loop_closed) {
      board_.logInfo("map: frame %llu recognised place %lld of the loaded map; the map pose is "
                     "in its frame now",
                     static_cast<unsigned long long>(sequence),
                     static_cast<long long>(result.loop_place_sequence));
    } else {
      keep_aside_ = true;
      board_.reportError("map %s: no place of it recognised by frame %llu, after the robot moved; "
                         "a new map is begun, and the loaded one will be kept as %s.unrecognised",
                         config_.path.string().c_str(), static_cast<unsigned long long>(sequence),
                         config_.path.string().c_str());
    }
  }
  relocalising_ = result.relocalising;
  if (foreign_ || config_.save_interval_s <= 0.0 || now < next_save_) return;
  {
    std::lock_guard lock(mutex_);
    if (pending_) return;  // the last one is still being written: the next frame tries again
  }
  next_save_ = now + std::chrono::duration_cast<SteadyClock::duration>(
                         std::chrono::duration<double>(config_.save_interval_s));
  if (!odometry.snapshotMap(snapshot_)) return;
  {
    std::lock_guard lock(mutex_);
    pending_ = true;
  }
  wake_.notify_one();
}

bool MapKeeper::saveNow(const Odometry& odometry) {
  std::unique_lock lock(mutex_);
  wake_.wait(lock, [&] { return !pending_; });
  if (foreign_ || !odometry.snapshotMap(snapshot_)) return false;
  const bool saved = write();
  if (saved)
    board_.logInfo("map %s: %d places saved", config_.path.string().c_str(),
                   snapshot_.place_count);
  return saved;
}

bool MapKeeper::write() {
  if (keep_aside_.exchange(false))
    board_.logInfo("map %s: the loaded map no frame recognised is %s", config_.path.string().c_str(),
                   keepAside(".unrecognised").c_str());
  if (const Expected<void> saved = map::saveMap(config_.path, snapshot_); !saved) {
    ++board_.map_save_failures;
    board_.reportError("map %s: not saved: %s", config_.path.string().c_str(),
                       saved.error().c_str());
    return false;
  }
  ++board_.maps_saved;
  return true;
}

void MapKeeper::saverLoop() {
  std::unique_lock lock(mutex_);
  for (;;) {
    wake_.wait(lock, [&] { return pending_ || stop_; });
    if (pending_) {
      // The frame thread does not touch snapshot_ while pending_ is set.
      lock.unlock();
      write();
      lock.lock();
      pending_ = false;
      wake_.notify_all();
      continue;
    }
    if (stop_) return;
  }
}

}  // namespace omnipose::daemon
