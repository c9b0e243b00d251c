#pragma once
/// \file imu_subscriber.hpp
/// The robot's gyro over LCM (daemon.yaml `imu: {source: lcm, channel, url}`): a thread of
/// its own receives omnipose.imu_t messages (decodeImuMessage()) and queues their samples
/// for the processing thread (GyroQueue), which gives them to the odometry before each
/// frame. Through LCM's C API (its C++ subscription callbacks trip GCC 12's UBSan vptr
/// check).
///
/// Faults are counted on the StatusBoard and reported, never fatal: a message that is not an
/// imu_t with a reading (imu_messages_bad), a sample that finds the queue full
/// (imu_samples_dropped), and the end of the stream (an LCM log that was read to its end,
/// a transport error): the thread then ends and the pipeline goes on from the images alone.
///
/// Realtime: the constructor allocates; receiving allocates nothing in this code (LCM's
/// own receive buffers are its business).

#include <atomic>
#include <string>

#include "daemon/gyro_queue.hpp"
#include "daemon/gyro_stream.hpp"
#include "daemon/status_board.hpp"

typedef struct _lcm_t lcm_t;
typedef struct _lcm_subscription_t lcm_subscription_t;
typedef struct _lcm_recv_buf_t lcm_recv_buf_t;

namespace omnipose::daemon {

class ImuSubscriber final : public GyroStream {
 public:
  /// Opens LCM at `url` ("" = LCM's default, udpm multicast; "file://PATH" reads a log) and
  /// subscribes to `channel`. Throws std::runtime_error naming the URL when LCM cannot be
  /// initialised. `queue` and `board` are borrowed and must outlive this.
  ImuSubscriber(const std::string& url, const std::string& channel, GyroQueue& queue,
                StatusBoard& board);
  /// Stops and joins the thread.
  ~ImuSubscriber() override;

  /// Whether the stream ended by itself (an LCM log read to its end, a transport error).
  bool ended() const { return ended_.load(); }
  /// One line for the start-up log.
  std::string describe() const override;

 private:
  void run() override;
  void receive(const void* data, int size);
  static void onMessage(const lcm_recv_buf_t* buffer, const char* channel, void* self);

  std::string url_, channel_;
  GyroQueue& queue_;
  StatusBoard& board_;
  lcm_t* lcm_ = nullptr;
  lcm_subscription_t* subscription_ = nullptr;
  std::atomic<bool> ended_{false};
};

}  // namespace omnipose::daemon
