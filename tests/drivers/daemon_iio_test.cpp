// The daemon with its gyro on a Linux IIO device: the fake device (fake_iio_device.hpp) plays
// a BMI160 whose scans carry a rendered turn's gyro (the rates quantised to the driver's
// scale), read by IioSubscriber into the odometry of a rolling-shutter dataset; an unplug and
// replug at another index mid-stream, counted once and found again by name; and the start-up
// errors (no such device, no gyro channels, no calibration imu section), each naming it.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>
#include <thread>
#include <vector>

#include "daemon/config.hpp"
#include "daemon/daemon.hpp"
#include "daemon/iio_subscriber.hpp"
#include "daemon_test_support.hpp"
#include "fake_iio_device.hpp"
#include "gyro_dataset.hpp"
#include "omnipose/io/gyro.hpp"

using ::testing::HasSubstr;

namespace omnipose {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using testing::FakeIioDevice;

constexpr double kScale = 0.000266;  // the fake BMI160's in_anglvel_scale, rad/s per LSB

/// The raw s16 reading of a rate (rad/s) at the BMI160's scale.
std::array<std::int64_t, 3> raw(const Eigen::Vector3d& rate) {
  std::array<std::int64_t, 3> r{};
  for (int k = 0; k < 3; ++k) r[static_cast<std::size_t>(k)] = std::llround(rate[k] / kScale);
  return r;
}

std::int64_t ns(double t) { return std::llround(t * 1e9); }

daemon::DaemonOptions onFake(FakeIioDevice& dev) {
  daemon::DaemonOptions o;
  o.force_lossless = true;
  o.iio_io = &dev;
  o.iio_sysfs_root = FakeIioDevice::Config{}.sysfs_root;
  o.iio_dev_root = FakeIioDevice::Config{}.dev_root;
  return o;
}

struct StatusBus {
  lcm::LCM lcm{"memq://"};
  std::vector<status_t> statuses;
  std::size_t poses = 0;
  StatusBus() {
    lcm.subscribe("OMNI_STATUS", &StatusBus::onStatus, this)->setQueueCapacity(1 << 20);
    lcm.subscribe("OMNI_POSE", &StatusBus::onPose, this)->setQueueCapacity(1 << 20);
  }
  void onStatus(const lcm::ReceiveBuffer*, const std::string&, const status_t* s) { statuses.push_back(*s); }
  void onPose(const lcm::ReceiveBuffer*, const std::string&, const pose_t*) { ++poses; }
  std::unique_ptr<daemon::MessageSink> sink() { return std::make_unique<testing::SharedLcmSink>(lcm); }
  void run(daemon::Daemon& d, std::chrono::seconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    d.start();
    while (!d.waitFinished(10ms)) {
      while (lcm.handleTimeout(0) > 0) {
      }
      if (std::chrono::steady_clock::now() > deadline) {
        ADD_FAILURE() << "daemon did not finish in time";
        d.requestStop();
      }
    }
    d.join();
    while (lcm.handleTimeout(0) > 0) {
    }
  }
};

DaemonConfig parse(const std::string& yaml) { return DaemonConfig::parse(yaml, "test.yaml", "/"); }

fs::path gyroDataset() {
  // The gyro's clock 0.5 s ahead of the recording's: every timestamp positive.
  return testing::cachedDataset("iio-gyro", [](const fs::path& dir) {
    testing::writeGyroDataset(dir, testing::indoorPhoto(), 13, 0.5);
  });
}

TEST(DaemonOnFakeIio, TheGyroOfAnIioDeviceTakesTheRollingShutterOut) {
  const fs::path dataset = gyroDataset();
  const auto samples = readGyroCsv(dataset / "imu.csv").samples;
  ASSERT_LT(samples.size(), 1000u) << "all fit in the device's buffer (length 1024)";
  FakeIioDevice dev;
  StatusBus bus;
  std::FILE* log = std::tmpfile();
  {
    daemon::Daemon d(parse(testing::fileSourceConfig(dataset, "memq://", true) +
                           "imu: {source: iio, device: bmi160, sampling_hz: 200}\n"),
                     log, nullptr, bus.sink(), onFake(dev));
    EXPECT_EQ(d.imuDescription(),
              "imu: iio:device0 (bmi160), anglvel x,y,z le:s16/16>>0 x 0.000266 rad/s, "
              "16-byte scans, clock monotonic, 200 Hz, trigger bmi160-dev0");
    EXPECT_TRUE(dev.bufferEnabled());
    // The device stamps on CLOCK_MONOTONIC as the recording's frames are timed here: the
    // dataset's imu.csv times, quantised to the driver's LSB.
    for (const GyroSample& s : samples) dev.pushScan(ns(s.t), raw(s.rate), {0, 0, 4096});
    bus.run(d, 120s);
  }
  std::fclose(log);
  EXPECT_FALSE(dev.bufferEnabled()) << "disabled at the daemon's end";
  EXPECT_EQ(dev.openFdCount(), 0);
  EXPECT_EQ(dev.violations(), std::vector<std::string>{});
  ASSERT_FALSE(bus.statuses.empty());
  const status_t& last = bus.statuses.back();
  EXPECT_EQ(last.imu_samples, static_cast<std::int64_t>(samples.size())) << "every rate arrived";
  EXPECT_EQ(last.imu_samples_refused + last.imu_messages_bad + last.imu_samples_dropped, 0);
  EXPECT_EQ(last.imu_device_lost, 0);
  // Realtime replay: a frame whose time has passed before the pipeline is ready for it is
  // dropped as a camera would drop it (lost upstream) or overwritten by a newer one (stale),
  // the more so under a sanitizer or on a busy machine; every frame is accounted for.
  EXPECT_EQ(last.frames_received, 13);
  EXPECT_EQ(last.frames_processed + last.frames_skipped_stale + last.frames_lost_upstream, 13);
  EXPECT_EQ(last.frames_bad, 0);
  EXPECT_GE(last.frames_processed, 5);
  EXPECT_GT(last.frames_with_gyro, 0);
  EXPECT_GE(last.frames_with_gyro, last.frames_processed - 1);
  EXPECT_EQ(last.frames_with_gyro + last.frames_without_gyro, last.frames_processed);
}

/// Waits until `done` or 10 s.
template <typename F>
bool waitFor(F done) {
  const auto deadline = std::chrono::steady_clock::now() + 10s;
  while (!done()) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(1ms);
  }
  return true;
}

TEST(IioSubscriber, AnUnplugIsCountedOnceAndTheDeviceIsFoundAgainAtItsNewIndex) {
  FakeIioDevice dev;
  daemon::GyroQueue queue;
  std::FILE* log = std::tmpfile();
  daemon::StatusBoard board(log);
  IioGyroOptions o;
  o.device = "bmi160";
  o.sysfs_root = FakeIioDevice::Config{}.sysfs_root;
  o.dev_root = FakeIioDevice::Config{}.dev_root;
  std::vector<GyroSample> got(200);
  std::size_t n = 0;
  const auto drain = [&] { n += queue.pop(std::span(got).subspan(n)); return n; };
  {
    daemon::IioSubscriber sub(o, dev, queue, board);
    sub.start();
    constexpr std::int64_t t0 = 7'000'000'000'000, dt = 2'500'000;  // 400 Hz
    for (int k = 0; k < 50; ++k) dev.pushScan(t0 + k * dt, {k, -k, 2 * k});
    EXPECT_TRUE(waitFor([&] { return drain() == 50; }));
    dev.replugAfterListings(3, 4);  // found by name at the fourth look, as iio:device4
    dev.unplug();
    EXPECT_TRUE(waitFor([&] { return dev.plugged() && dev.bufferEnabled(); }));
    for (int k = 50; k < 100; ++k) dev.pushScan(t0 + k * dt, {k, -k, 2 * k});
    EXPECT_TRUE(waitFor([&] { return drain() == 100; }));
    EXPECT_EQ(board.snapshot().imu_device_lost, 1);
    EXPECT_EQ(board.snapshot().imu_messages_bad, 0);
    // A garbage scan after the replug: counted, skipped, the stream goes on.
    dev.pushScan(t0, {1, 1, 1});  // back in time
    dev.pushScan(t0 + 100 * dt, {32767, 0, 0});  // at the rail
    dev.pushScan(t0 + 101 * dt, {5, 5, 5});
    EXPECT_TRUE(waitFor([&] { return drain() == 101; }));
    EXPECT_EQ(board.snapshot().imu_messages_bad, 2);
    sub.stop();
  }
  EXPECT_EQ(dev.index(), 4);
  EXPECT_FALSE(dev.bufferEnabled());
  EXPECT_EQ(dev.openFdCount(), 0);
  EXPECT_EQ(dev.violations(), std::vector<std::string>{});
  for (std::size_t k = 0; k < 100; ++k) {
    EXPECT_DOUBLE_EQ(got[k].t, (7'000'000'000'000 + static_cast<double>(k) * 2'500'000) * 1e-9);
    EXPECT_DOUBLE_EQ(got[k].rate.z(), 2.0 * static_cast<double>(k) * kScale);
  }
  std::rewind(log);
  std::string text(1 << 16, '\0');
  text.resize(std::fread(text.data(), 1, text.size(), log));
  std::fclose(log);
  EXPECT_THAT(text, HasSubstr("imu: iio:device0 (bmi160): the device went away (ENODEV); closed, "
                              "looked for again every 500 ms"));
  EXPECT_THAT(text, HasSubstr("imu: iio:device4 (bmi160), anglvel"));
  EXPECT_THAT(text, HasSubstr("is back"));
}

TEST(DaemonOnFakeIio, AMissingOrUnsuitableDeviceIsAStartUpErrorNamingIt) {
  const fs::path dataset = gyroDataset();
  const std::string base = testing::fileSourceConfig(dataset, "memq://", false);
  const auto startupError = [&](FakeIioDevice& dev, const std::string& imu) {
    StatusBus bus;
    try {
      daemon::Daemon d(parse(base + imu), stderr, nullptr, bus.sink(), onFake(dev));
    } catch (const std::runtime_error& e) {
      EXPECT_EQ(dev.openFdCount(), 0);
      EXPECT_FALSE(dev.bufferEnabled());
      return std::string(e.what());
    }
    ADD_FAILURE() << "no error for " << imu;
    return std::string();
  };
  FakeIioDevice dev;
  EXPECT_THAT(startupError(dev, "imu: {source: iio, device: lsm6dsx}\n"),
              HasSubstr("imu.device: iio device \"lsm6dsx\": no device of that name under "
                        "/fake/sys/bus/iio/devices"));
  EXPECT_THAT(startupError(dev, "imu: {source: iio, device: iio:device3}\n"),
              HasSubstr("imu.device: iio device iio:device3: not under /fake/sys/bus/iio/devices"));
  FakeIioDevice::Config adc;
  adc.name = "ads1015";
  adc.channels = {{"in_voltage0", 0, "be:s12/16>>4", false}, {"in_timestamp", 4, "le:s64/64>>0", false}};
  FakeIioDevice not_a_gyro(adc);
  EXPECT_THAT(startupError(not_a_gyro, "imu: {source: iio, device: ads1015}\n"),
              HasSubstr("imu.device: iio:device0 (ads1015) has no gyro channels"));
  // Without the calibration's imu section the device is not even opened.
  testing::TempDir tmp("iio");
  Calibration without = Calibration::load(dataset / "calibration.yaml");
  without.imu.reset();
  without.save(tmp / "calibration.yaml");
  const std::string no_imu = "source: {type: file, path: " + dataset.string() +
                             "}\ncalibration: " + (tmp / "calibration.yaml").string() + "\n";
  StatusBus bus;
  try {
    daemon::Daemon d(parse(no_imu + "imu: {source: iio, device: bmi160}\n"), stderr, nullptr,
                     bus.sink(), onFake(dev));
    ADD_FAILURE() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_THAT(e.what(), HasSubstr("imu.source: iio needs the calibration's imu section"));
  }
  EXPECT_EQ(dev.enableCount(), 0);
}

}  // namespace
}  // namespace omnipose
