#pragma once
/// \file processor.hpp
/// The processing thread's work: for each frame taken from the mailbox, run the odometry
/// (omnipose/odometry.hpp: the same frame-to-pose policy as omnipose-replay), encode an omnipose::pose_t (and, when enabled, a fit_diagnostics_t)
/// into preallocated structs and buffers, and publish them; at the status rate, encode and
/// publish an omnipose::status_t. With lcm.panorama_channel, a panorama picture now and then
/// (panorama_pictures.hpp: made on a thread of its own, published here at a later frame).
///
/// Pose semantics (see lcm_types/pose_t.lcm and odometry.hpp): a gap (mailbox gap flag:
/// a bad frame, a source reconnect, a looped recording) or a frame the pipeline rejects
/// (counted as bad, reported, no pose) makes the odometry register the next frame against
/// its keyframe, with the heading found by a whole-ring search; only when that fails, and
/// for the first frame, is a new chain segment started and the frame published with
/// STATUS_LOST, zero relative motion and an infinite covariance. Stale frames skipped by the
/// mailbox are not a gap: the next frame is registered directly against the last processed
/// one (`reference_sequence`), and `frames_skipped` says how many were dropped in between.
///
/// Realtime: the constructor allocates everything (pipeline, messages sized for the
/// window count, encode buffers, sample rings); handleFrame() and publishStatus() allocate
/// nothing in this code (what the sink's transport does is its own business, see
/// message_sink.hpp) and never throw. One instance, used by one thread at a time.

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>
#include <vector>

#include "daemon/frame_mailbox.hpp"
#include "daemon/gyro_queue.hpp"
#include "daemon/map_keeper.hpp"
#include "daemon/message_sink.hpp"
#include "daemon/panorama_pictures.hpp"
#include "daemon/sample_ring.hpp"
#include "daemon/status_board.hpp"
#include "daemon/wall_clock.hpp"
#include "daemon/config.hpp"
#include "omnipose/odometry.hpp"

namespace omnipose {
class pose_t;
class status_t;
class fit_diagnostics_t;
}  // namespace omnipose

namespace omnipose::daemon {

class Processor {
 public:
  /// Samples kept for the percentiles in status_t.
  static constexpr std::size_t kSamples = 256;

  /// Builds the pipeline (throws std::invalid_argument listing bad options) and sizes
  /// every message. `sink` and `board` are borrowed and must outlive this.
  /// `source_description` goes into status_t.source. `gyro` (borrowed, may be null): the
  /// robot's gyro samples, given to the odometry before each frame. `map_file`: with a
  /// path, the map is loaded from it here and saved to it (map_keeper.hpp).
  Processor(const Calibration& calibration, const OdometryOptions& odometry,
            const LcmConfig& lcm, MessageSink& sink, StatusBoard& board,
            const std::string& source_description, GyroQueue* gyro = nullptr,
            const MapFileConfig& map_file = {});
  ~Processor();
  Processor(const Processor&) = delete;
  Processor& operator=(const Processor&) = delete;

  /// Processes one frame and publishes its pose (and diagnostics). Allocation-free.
  void handleFrame(const MailboxFrame& frame);
  /// Publishes a status message (`final`: the last one before exit). Allocation-free.
  void publishStatus(bool final);
  /// After the last frame: saves the map (loop_closure.map_file). Not realtime.
  void finish();

 private:
  bool publish(const std::string& channel, std::vector<std::uint8_t>& buffer, int size);
  bool publish(const std::string& channel, std::span<const std::uint8_t> message);
  /// Publishes the panorama picture made since the last frame, and offers this one.
  void pictures(const MailboxFrame& frame);
  /// The load fields of a status over `wall_s` seconds: since the last status, or the run.
  void fillLoad(status_t& s, bool final, double wall_s);
  void fillDiagnostics(const FrameInfo& info, const OdometryResult& result, std::int8_t status);
  /// What the odometry is told of `frame` besides its pixels: its time (see the definition),
  /// number, a gap before it, and the exposure its source reported.
  static FrameStamp stampOf(const MailboxFrame& frame);
  /// Gives the odometry the gyro samples queued since the last frame.
  void takeGyro();
  /// After the frame `stamp` (its time on the odometry's clock): the odometry's gyro counters
  /// to the board, a report of the frame when the gyro's samples did not cover it (with a
  /// gyro stream configured), and one when the exposure its source reported was refused.
  void countGyro(const FrameStamp& stamp);
  /// After a frame the odometry took: its places, a closed loop, and the map's registrations
  /// and refusals (LoopClosureCounters) to the board.
  void countMap(const OdometryResult& result);

  Odometry odometry_;
  LcmConfig lcm_;
  MessageSink& sink_;
  StatusBoard& board_;
  bool diagnostics_ = false;
  GyroQueue* gyro_ = nullptr;
  std::int64_t frames_without_gyro_ = 0;  ///< GyroCounters' at the last frame
  std::int64_t exposures_refused_ = 0;    ///< GyroCounters' at the last frame
  std::array<GyroSample, 256> gyro_batch_;  ///< takeGyro()'s scratch

  std::unique_ptr<pose_t> pose_;
  std::unique_ptr<status_t> status_;
  std::unique_ptr<fit_diagnostics_t> diagnostics_msg_;
  std::unique_ptr<PanoramaPictures> pictures_;  ///< lcm.panorama_channel set
  std::unique_ptr<MapKeeper> map_keeper_;       ///< loop_closure.map_file set
  std::vector<std::uint8_t> pose_buffer_;
  std::vector<std::uint8_t> status_buffer_;
  std::vector<std::uint8_t> diagnostics_buffer_;
  std::vector<char> error_text_;

  SampleRing<kSamples> processing_ms_;
  SampleRing<kSamples> latency_ms_;
  SteadyClock::time_point started_;
  SteadyClock::time_point last_status_time_;
  std::int64_t last_status_received_ = 0;
  std::int64_t last_status_processed_ = 0;
  /// Load accounting (status_t.cpu_cores, processing_cpu_share, worker_wait_ms,
  /// frames_waited_share): totals
  /// since start-up, and their values at the last status. Nanoseconds, seconds for the wait.
  struct LoadTotals {
    std::int64_t process_cpu_ns = 0;     ///< CLOCK_PROCESS_CPUTIME_ID
    std::int64_t processing_wall_ns = 0;  ///< in Odometry::process()
    std::int64_t processing_cpu_ns = 0;   ///< of it, this thread's CLOCK_THREAD_CPUTIME_ID
    double worker_wait_s = 0;             ///< Odometry::workerWaitSeconds()
    std::int64_t frames_waited = 0;       ///< Odometry::framesWaitedForWorkers()
    std::int64_t frames = 0;              ///< frames given to Odometry::process()
  };
  LoadTotals load_;
  LoadTotals load_at_start_;   ///< after the constructor: the start-up's CPU time is not load
  LoadTotals load_at_status_;
};

}  // namespace omnipose::daemon
