#pragma once
/// \file map_keeper.hpp
/// The daemon's map on disk (loop_closure.map_file; DESIGN.md section 5, "The map across
/// restarts"). At start-up the file is loaded into the odometry, whose frames then
/// relocalise in it (Odometry::restoreMap()); while running, a snapshot of the map is taken
/// on the frame's thread every save_interval_s (Odometry::snapshotMap(): a copy, no
/// allocation) and written by a thread of its own, atomically (map_file.hpp: a kill leaves
/// the old file or the new one); at shutdown the map is saved once more.
///
/// A file that cannot be used never stops the daemon: it starts with an empty map, and says
/// why, naming the file. A damaged map (cut short, a bad checksum, another version or
/// panorama size, another calibration's lens, too many places) is kept aside as
/// `<map_file>.refused` and a new map is saved in its place; a file that is not an omnipose
/// map is left alone and the map is not saved (saving would overwrite it). A loaded map in
/// which no frame is recognised (the odometry drops it once the robot has moved and begins a
/// new one) is kept aside as `<map_file>.unrecognised` before the new map is first saved over
/// it. Saves and failures are counted (StatusBoard).

#include <atomic>
#include <condition_variable>
#include <cstdint>
#include <mutex>
#include <string>
#include <thread>

#include "daemon/config.hpp"
#include "daemon/status_board.hpp"
#include "daemon/wall_clock.hpp"
#include "map/map_file.hpp"
#include "omnipose/odometry.hpp"

namespace omnipose::daemon {

class MapKeeper {
 public:
  /// `board` (borrowed) receives the counts and the log lines; `max_places`: the odometry's
  /// LoopClosureOptions::max_places (a file with more is refused). Starts the saver thread.
  MapKeeper(const MapFileConfig& config, int max_places, StatusBoard& board);
  /// Stops the saver thread (a save under way is finished first).
  ~MapKeeper();
  MapKeeper(const MapKeeper&) = delete;
  MapKeeper& operator=(const MapKeeper&) = delete;

  /// Loads the file into `odometry` (see the file comment) and makes room for the snapshots.
  /// Call once, before the first frame.
  void load(Odometry& odometry, const Calibration& calibration);
  /// After a frame (`result`, the frame's `sequence`), on the frame's thread: logs the frame
  /// that recognises a place of the loaded map, and the loaded map's being dropped (its file is
  /// then kept aside at the next save); every save_interval_s (when the saver is idle) the map
  /// is copied and handed to the saver. Allocation-free but for those two log lines, never
  /// blocks on the disk.
  void afterFrame(const Odometry& odometry, const OdometryResult& result, std::uint64_t sequence,
                  SteadyClock::time_point now);
  /// Waits for a save under way, then saves the map on this thread (shutdown). False when it
  /// could not be saved (logged).
  bool saveNow(const Odometry& odometry);

 private:
  void saverLoop();
  /// Writes snapshot_ (counted, a failure logged), first keeping the dropped loaded map
  /// aside when keep_aside_ is set; true on success.
  bool write();
  /// Renames the map file to `<map_file><suffix>` (replacing an older one); what became of
  /// it, for the log.
  std::string keepAside(const char* suffix) const;

  MapFileConfig config_;
  StatusBoard& board_;
  int max_places_;
  /// The file is not an omnipose map: never written.
  bool foreign_ = false;
  /// The last frame's OdometryResult::relocalising (frame thread).
  bool relocalising_ = false;
  /// The loaded map was dropped: its file is kept aside before the next write.
  std::atomic<bool> keep_aside_ = false;
  SteadyClock::time_point next_save_;
  map::MapSnapshot snapshot_;  ///< the saver's while pending_, the frame thread's otherwise

  std::mutex mutex_;
  std::condition_variable wake_;
  bool pending_ = false;  ///< snapshot_ waits to be written
  bool stop_ = false;
  std::thread saver_;
};

}  // namespace omnipose::daemon
