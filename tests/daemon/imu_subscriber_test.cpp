// The daemon's gyro over LCM (src/daemon/imu_subscriber.hpp), fed from an LCM event log
// (file:// URL, nothing on the network): every good sample reaches the queue in order, bad
// messages are counted and named, a full queue counts what it drops, and the end of the
// stream ends the thread without harm.
#include "daemon/imu_subscriber.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <limits>
#include <string>
#include <thread>
#include <vector>

#include "daemon_test_support.hpp"

using ::testing::HasSubstr;

namespace omnipose::daemon {
namespace {
namespace fs = std::filesystem;

using testing::LcmEvent;

LcmEvent imuEvent(double t, double wz, const std::string& channel = "OMNI_IMU") {
  return testing::imuEvent({t, Eigen::Vector3d(0.01, -0.02, wz)}, channel);
}

class ImuSubscriberTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("omnipose_imu_subscriber_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  /// Runs a subscriber on the log of `events` until the log ends (at most 10 s).
  void receive(const std::vector<LcmEvent>& events, GyroQueue& queue, StatusBoard& board) {
    testing::writeLcmLog(dir_ / "imu.lcm", events);
    ImuSubscriber subscriber("file://" + (dir_ / "imu.lcm").string() + "?speed=0", "OMNI_IMU",
                             queue, board);
    subscriber.start();
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(10);
    while (!subscriber.ended() && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    EXPECT_TRUE(subscriber.ended());
    subscriber.stop();
  }
  fs::path dir_;
};

TEST_F(ImuSubscriberTest, EverySampleReachesTheQueueInOrderAndBadMessagesAreCounted) {
  std::vector<LcmEvent> events;
  for (int i = 0; i < 200; ++i) {
    events.push_back(imuEvent(10.0 + 0.005 * i, 0.001 * i));
    if (i == 50) events.push_back({"OMNI_IMU", {1, 2, 3}});                // not an imu_t
    if (i == 60) events.push_back(imuEvent(10.3, std::numeric_limits<double>::infinity()));
    if (i == 70) events.push_back(imuEvent(10.35, 1.0, "OTHER"));           // another channel
  }
  GyroQueue queue;
  std::FILE* log = std::tmpfile();
  StatusBoard board(log);
  receive(events, queue, board);

  std::array<GyroSample, 512> out{};
  ASSERT_EQ(queue.pop(out), 200u);
  for (int i = 0; i < 200; ++i) {
    EXPECT_NEAR(out[i].t, 10.0 + 0.005 * i, 1e-6);
    EXPECT_EQ(out[i].rate.z(), 0.001 * i);
    EXPECT_EQ(out[i].rate.x(), 0.01);
  }
  const DaemonStats stats = board.snapshot();
  EXPECT_EQ(stats.imu_messages_bad, 2);
  EXPECT_EQ(stats.imu_samples_dropped, 0);
  char text[512];
  EXPECT_GT(board.lastError(text, sizeof(text)), 0);
  EXPECT_THAT(text, HasSubstr("imu: the stream on channel OMNI_IMU"));
  std::rewind(log);
  std::string logged(1 << 14, '\0');
  logged.resize(std::fread(logged.data(), 1, logged.size(), log));
  std::fclose(log);
  // The first fault's line (those within 200 ms after it are counted, not logged).
  EXPECT_THAT(logged, HasSubstr("imu: 3 bytes are not an omnipose.imu_t (too short, or another "
                                "type), on channel OMNI_IMU"));
}

TEST_F(ImuSubscriberTest, AFullQueueCountsWhatItDrops) {
  std::vector<LcmEvent> events;
  const int n = static_cast<int>(GyroQueue::kCapacity) + 100;
  for (int i = 0; i < n; ++i) events.push_back(imuEvent(1.0 + 0.001 * i, 0.5));
  GyroQueue queue;
  StatusBoard board(nullptr);
  receive(events, queue, board);  // nothing takes samples out meanwhile
  EXPECT_EQ(board.snapshot().imu_samples_dropped, 100);
  std::array<GyroSample, 64> out{};
  std::size_t popped = 0;
  for (std::size_t k; (k = queue.pop(out)) > 0;) popped += k;
  EXPECT_EQ(popped, GyroQueue::kCapacity);
}

TEST_F(ImuSubscriberTest, AnUnusableUrlIsAStartUpErrorNamingIt) {
  GyroQueue queue;
  StatusBoard board(nullptr);
  try {
    ImuSubscriber s("nosuch://x", "OMNI_IMU", queue, board);
    FAIL() << "no error";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("imu.url \"nosuch://x\""));
  }
}

}  // namespace
}  // namespace omnipose::daemon
