#pragma once
/// \file counters.hpp
/// The daemon's counters, defined once: the table below. Each counter is a total since
/// start-up (a count of frames, messages or events; never negative, never reset). From the
/// table derive StatusBoard's lock-free atomics, the DaemonStats snapshot, the copy into the
/// LCM status_t (same field names, lcm_types/status_t.lcm) and the log line of the counters.
/// Adding a counter is one line here plus its `int64_t` field in status_t.lcm (appended at
/// the end of the struct); a counter without its .lcm field does not compile.
///
/// Every frame is counted exactly once. Once the capture and processing threads have
/// finished (the final status):
///   frames_received = frames_processed + frames_skipped_stale + frames_bad
///                     + frames_lost_upstream
/// While they run, a frame is counted as received before its fate is, so received may be
/// ahead by the frames in flight (at most the mailbox's slots), never behind.
/// frames_implausible is a part of frames_bad (not a fate of its own).
///
/// Header-only, no dependency beyond <cstdint>: tools (omnipose-listen) print status_t's
/// counters through it as well.

#include <cstdint>

/// X(name, label, description) for each counter, in the order log lines list them.
/// `name`: the field of StatusBoard, DaemonStats and status_t; `label`: how log lines name it.
#define OMNIPOSE_DAEMON_COUNTERS(X)                                                          \
  X(frames_received, "received",                                                             \
    "frames the source delivered, reported bad, or is known to have dropped")                \
  X(frames_processed, "processed", "frames the pipeline ran on (= poses published)")          \
  X(frames_skipped_stale, "skipped (stale)",                                                 \
    "frames overwritten by a newer one before processing, or never processed because the "   \
    "daemon stopped")                                                                        \
  X(frames_bad, "bad", "corrupt / wrong-size frames and frames the pipeline rejected")        \
  X(frames_lost_upstream, "lost upstream",                                                   \
    "frames the source or driver dropped (gaps in its sequence numbers)")                    \
  X(poses_lost, "lost poses", "poses published with STATUS_LOST")                            \
  X(source_failures, "source failures",                                                      \
    "times the source failed and was closed to be re-opened (one per outage)")               \
  X(publish_failures, "publish failures", "messages that could not be encoded or published")  \
  X(frames_implausible, "implausible",                                                       \
    "of the bad frames, those that decoded but were not believed (a glitching camera)")       \
  X(imu_samples, "gyro samples", "gyro samples the odometry took (daemon.yaml imu)")          \
  X(imu_samples_refused, "gyro samples refused",                                             \
    "gyro samples not finite, beyond 100 rad/s, or stamped at or before the one before")     \
  X(imu_messages_bad, "bad imu messages",                                                     \
    "messages on the imu channel that are not an omnipose.imu_t with a reading; with an "    \
    "iio gyro, its scans skipped (partial, timestamp zero or not after the one before, a "  \
    "rate at the sensor's rail)")                                                           \
  X(imu_samples_dropped, "gyro samples dropped",                                             \
    "gyro samples that arrived while the queue to the processing thread was full")           \
  X(imu_clock_restarts, "gyro clock restarts",                                               \
    "times the gyro's clock jumped back by more than a second (its samples before dropped)") \
  X(frames_with_gyro, "frames with gyro",                                                     \
    "rolling-shutter frames whose rows' rotations came from the gyro")                       \
  X(frames_without_gyro, "frames without gyro",                                               \
    "rolling-shutter frames (calibration with an imu section) the gyro did not cover")       \
  X(frames_gyro_bridged, "gyro-bridged",                                                      \
    "gaps the images could not bridge and the gyro did (pose_t TRACK_GYRO)")                 \
  X(imu_device_lost, "gyro device lost",                                                      \
    "times the iio gyro went away or failed (unplugged, driver unbound, a read error) and "  \
    "was closed to be looked for again every 0.5 s")                                        \
  X(loops_closed, "loops closed",                                                            \
    "frames that closed a loop with a place seen before (pose_t loop_closed)")                \
  X(map_registrations, "map registrations",                                                  \
    "frames registered against a place of the map (loop_closure; LoopClosureCounters)")       \
  X(map_refused_no_heading, "map refused (no heading)",                                      \
    "registrations refused: the whole-ring search found no clear heading")                   \
  X(map_refused_turned, "map refused (turned)",                                              \
    "registrations refused: turned farther than max_correction_deg from the prediction")     \
  X(map_refused_fit, "map refused (fit)",                                                    \
    "registrations refused: the fit was not ok, or used under half the windows")             \
  X(map_refused_too_far, "map refused (too far)",                                            \
    "registrations refused: the fit puts the frame beyond search_radius")                    \
  X(map_verified, "map verified", "registrations that passed every test")                    \
  X(map_disagreed, "map disagreed",                                                          \
    "relocalisation checks whose two places matched the frame but disagreed on where it is")

namespace omnipose::daemon {

/// Number of counters in the table.
inline constexpr int kCounterCount = 0
#define OMNIPOSE_COUNT_ONE(name, label, description) +1
    OMNIPOSE_DAEMON_COUNTERS(OMNIPOSE_COUNT_ONE)
#undef OMNIPOSE_COUNT_ONE
    ;

/// Calls `f(label, counters.<name>)` for every counter, in table order. `counters` is
/// anything with the counter fields: a DaemonStats or a status_t (integers), a StatusBoard
/// (atomics); non-const, `f` may change them.
template <typename Counters, typename F>
void forEachCounter(Counters&& counters, F&& f) {
#define OMNIPOSE_VISIT_ONE(name, label, description) f(label, counters.name);
  OMNIPOSE_DAEMON_COUNTERS(OMNIPOSE_VISIT_ONE)
#undef OMNIPOSE_VISIT_ONE
}

/// Copies every counter field from `from` to `to`: StatusBoard -> DaemonStats (each atomic
/// loaded on its own: lock-free, not one instant), DaemonStats -> status_t. Allocation-free.
template <typename From, typename To>
void copyCounters(const From& from, To& to) {
#define OMNIPOSE_COPY_ONE(name, label, description) to.name = from.name;
  OMNIPOSE_DAEMON_COUNTERS(OMNIPOSE_COPY_ONE)
#undef OMNIPOSE_COPY_ONE
}

}  // namespace omnipose::daemon
