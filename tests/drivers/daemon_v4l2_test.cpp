// The daemon end to end on a V4L2 camera: the fake device (fake_v4l2_device.hpp) streams
// omni frames rendered by the exact renderer, in YUYV or MJPG, through V4l2Source into the
// daemon; poses come out over LCM memq:// and are checked against the renderer's ground
// truth. Also: an unplug/replug mid-stream, re-opened by the daemon's capture loop (the one
// owner of reconnection) on V4L2 and on a fake libcamera, the
// source factory building the camera sources, and a missing device as a start-up error.

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <fstream>

#include <lcm/lcm-cpp.hpp>

#include <Eigen/Geometry>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <string>
#include <thread>
#include <vector>

#include "daemon/daemon.hpp"
#include "daemon/message_sink.hpp"
#include "daemon/source_factory.hpp"
#include "fake_libcamera.hpp"
#include "fake_v4l2_device.hpp"
#include "libcamera/libcamera_source.hpp"
#include "omnipose/calibration.hpp"
#include "daemon/config.hpp"
#include "omnipose/pose_t.hpp"
#include "omnipose/status_t.hpp"
#include "omnipose/synth/synth.hpp"
#include "shared_lcm_sink.hpp"
#include "test_files.hpp"
#include "omnipose/io/trajectory.hpp"
#include "v4l2/v4l2_source.hpp"

using ::testing::HasSubstr;

namespace omnipose {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using testing::FakeV4l2Device;

constexpr int kFrames = 16;


/// Rendered omni frames of the "yaw" preset and their ground-truth poses (rendered once).
struct Rendered {
  std::vector<cv::Mat> frames;  // CV_8UC1, Calibration{} omni size
  std::vector<StampedPose> poses;
};
const Rendered& rendered() {
  static const Rendered r = [] {
    Rendered out;
    synth::MotionScript script = synth::MotionScript::preset("yaw");
    script.frames = kFrames;
    script.seed = 11;
    out.poses = synth::generateTrajectory(script);
    const synth::Renderer renderer(
        synth::Scene::load(fs::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg",
                           synth::SceneKind::kSphere),
        Calibration{}, {synth::OutputKind::kOmni, 1});
    for (const auto& p : out.poses) {
      cv::Mat grey;
      renderer.render(p.pose).convertTo(grey, CV_8U);
      out.frames.push_back(grey);
    }
    return out;
  }();
  return r;
}

cv::Size omniSize() { return {Calibration{}.omni.image_width, Calibration{}.omni.image_height}; }

/// Whether, by `status`, every frame the daemon received has been processed (or counted as
/// skipped, bad or lost) and the poses of the processed ones (`poses` of them) have arrived.
bool nothingInFlight(const status_t& status, std::size_t poses) {
  return status.frames_received == status.frames_processed + status.frames_skipped_stale +
                                       status.frames_bad + status.frames_lost_upstream &&
         static_cast<std::int64_t>(poses) == status.frames_processed;
}

struct Bus {
  lcm::LCM lcm{"memq://"};
  std::vector<pose_t> poses;
  std::vector<status_t> statuses;
  Bus() {
    lcm.subscribe("OMNI_POSE", &Bus::onPose, this)->setQueueCapacity(1 << 20);
    lcm.subscribe("OMNI_STATUS", &Bus::onStatus, this)->setQueueCapacity(1 << 20);
  }
  void onPose(const lcm::ReceiveBuffer*, const std::string&, const pose_t* p) { poses.push_back(*p); }
  void onStatus(const lcm::ReceiveBuffer*, const std::string&, const status_t* s) {
    statuses.push_back(*s);
  }
  void drain() {
    while (lcm.handleTimeout(0) > 0) {
    }
  }
  /// Runs the daemon until `poses` poses arrived (or `timeout`), then stops it.
  void run(daemon::Daemon& d, std::size_t poses_wanted, std::chrono::seconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    d.start();
    while (!d.waitFinished(10ms)) {
      drain();
      if (poses.size() >= poses_wanted) d.requestStop();
      if (std::chrono::steady_clock::now() > deadline) {
        ADD_FAILURE() << "daemon did not deliver " << poses_wanted << " poses in time";
        d.requestStop();
      }
    }
    d.join();
    drain();
  }
};

/// The fake camera's path: one that does not exist, so no test takes the lock of a real
/// camera of the machine (instance_lock.hpp) and parallel tests do not refuse each other.
constexpr const char* kFakeDevice = "/dev/video-omnipose-fake";

std::string daemonYaml(const fs::path& calibration, const std::string& format,
                       const std::string& device = kFakeDevice) {
  const cv::Size s = omniSize();
  return "source: {type: v4l2, device: " + device + ", width: " + std::to_string(s.width) +
         ", height: " + std::to_string(s.height) + ", fps: 30, format: " + format +
         "}\ncalibration: " + calibration.string() + "\nlcm: {url: 'memq://', status_hz: 5}\n";
}

/// The fake streams the rendered frames in order, then stops (the camera goes quiet).
std::unique_ptr<FakeV4l2Device> renderedCamera(int jpeg_quality = 95) {
  FakeV4l2Device::Config fc;
  fc.path = kFakeDevice;
  fc.content_cycle = kFrames;
  fc.jpeg_quality = jpeg_quality;
  fc.stride_align = 64;
  auto fake = std::make_unique<FakeV4l2Device>(fc);
  fake->setContent([](std::uint64_t frame, cv::Size size) {
    const cv::Mat& f = rendered().frames.at(frame);
    EXPECT_EQ(f.size(), size);
    return f.clone();
  });
  fake->stallAfter(kFrames);
  return fake;
}

/// Lossless pacing: the capture thread asks for the next frame only when the processor took
/// the last one.
daemon::DaemonOptions losslessOptions() {
  daemon::DaemonOptions o;
  o.force_lossless = true;
  return o;
}

/// Wall-clock microseconds the source reports for a frame the fake stamped at `mono_ns`.
std::int64_t wallUs(const FakeV4l2Device& fake, std::int64_t mono_ns) {
  return (mono_ns + fake.realtimeOffset() + 500) / 1000;
}

/// Maps every published pose to the rendered frame it was computed on, through its capture
/// time (which the fake recorded per frame), and checks the relative rotations.
void expectPosesMatchGroundTruth(const std::vector<pose_t>& poses, const FakeV4l2Device& fake,
                                 double max_error_rad, int* ok_count) {
  // Content index of each capture time the fake produced.
  std::map<std::int64_t, std::int64_t> content_of_utime;
  std::map<std::int64_t, std::int64_t> content_of_sequence;
  for (const pose_t& p : poses) {
    // Frame stamps are whole microseconds of CLOCK_MONOTONIC: try the neighbours.
    std::int64_t content = -1;
    const std::int64_t base = (p.utime * 1000 - fake.realtimeOffset()) / 1000 * 1000;
    for (std::int64_t probe = base - 1000; probe <= base + 1000 && content < 0; probe += 1000)
      if (wallUs(fake, probe) == p.utime) content = fake.contentIndexAt(probe);
    ASSERT_GE(content, 0) << "pose " << p.sequence << " has a capture time no frame had";
    content_of_sequence[p.sequence] = content;
  }
  *ok_count = 0;
  const auto& gt = rendered().poses;
  for (const pose_t& p : poses) {
    if (p.status == pose_t::STATUS_LOST) continue;
    ASSERT_TRUE(content_of_sequence.contains(p.reference_sequence));
    const std::int64_t i = content_of_sequence[p.reference_sequence];
    const std::int64_t j = content_of_sequence[p.sequence];
    const Eigen::Matrix3d truth =
        (gt[static_cast<std::size_t>(i)].pose.inverse() * gt[static_cast<std::size_t>(j)].pose)
            .rotation();
    const Eigen::Matrix3d measured = rotationFromVector(
        Eigen::Vector3d(p.rotation_vector[0], p.rotation_vector[1], p.rotation_vector[2]));
    const double err = Eigen::AngleAxisd(truth.transpose() * measured).angle();
    EXPECT_LT(err, max_error_rad) << "frames " << i << " -> " << j;
    ++*ok_count;
  }
}

class DaemonOnFakeV4l2 : public ::testing::TestWithParam<const char*> {};

TEST_P(DaemonOnFakeV4l2, RenderedOmniFramesGivePosesMatchingTheGroundTruth) {
  const std::string format = GetParam();
  testing::TempDir tmp("v4l2");
  Calibration{}.save(tmp.path() / "calibration.yaml");
  const DaemonConfig config =
      DaemonConfig::parse(daemonYaml(tmp.path() / "calibration.yaml", format), "test.yaml", tmp.path());
  auto fake = renderedCamera();
  Bus bus;
  {
    // Lossless pacing: the capture thread asks for the next frame only when the processor
    // took the last one; the fake's virtual clock jumps to it, so every frame is processed.
    daemon::Daemon d(config, stderr, std::make_unique<V4l2Source>(daemon::v4l2Options(config.source), fake.get()),
                     std::make_unique<testing::SharedLcmSink>(bus.lcm), losslessOptions());
    EXPECT_THAT(d.sourceDescription(), HasSubstr("v4l2 /dev/video-omnipose-fake 720x720"));
    bus.run(d, kFrames, 120s);
    const auto stats = d.stats();
    EXPECT_EQ(stats.frames_received, kFrames);
    EXPECT_EQ(stats.frames_processed, kFrames);
    EXPECT_EQ(stats.frames_bad, 0);
    EXPECT_EQ(stats.source_failures, 0);
  }
  EXPECT_TRUE(fake->violations().empty()) << ::testing::PrintToString(fake->violations());
  EXPECT_EQ(fake->openFdCount(), 0) << "the daemon closed the device";
  EXPECT_EQ(fake->mappingCount(), 0);

  ASSERT_EQ(bus.poses.size(), static_cast<std::size_t>(kFrames));
  for (std::size_t k = 0; k < bus.poses.size(); ++k) {
    const pose_t& p = bus.poses[k];
    EXPECT_EQ(p.sequence, static_cast<std::int64_t>(k)) << "the driver's sequence numbers";
    EXPECT_EQ(p.utime, wallUs(*fake, fake->frameTimestampNs(k))) << "capture time, wall clock";
    if (k == 0) {
      EXPECT_EQ(p.status, pose_t::STATUS_LOST);
    } else {
      EXPECT_EQ(p.status, pose_t::STATUS_OK) << k;
      EXPECT_EQ(p.reference_sequence, p.sequence - 1);
      EXPECT_EQ(p.frames_skipped, 0);
    }
  }
  int ok = 0;
  expectPosesMatchGroundTruth(bus.poses, *fake, 0.01, &ok);
  EXPECT_EQ(ok, kFrames - 1);
  ASSERT_FALSE(bus.statuses.empty());
  EXPECT_TRUE(bus.statuses.back().final);
  EXPECT_THAT(bus.statuses.back().source, HasSubstr("v4l2 /dev/video-omnipose-fake"));
}

INSTANTIATE_TEST_SUITE_P(Formats, DaemonOnFakeV4l2, ::testing::Values("YUYV", "MJPG", "GREY"));

TEST(DaemonOnFakeV4l2Unplug, DeviceVanishingMidStreamIsReopenedByTheCaptureLoopAndCountedOnce) {
  testing::TempDir tmp("v4l2");
  Calibration{}.save(tmp.path() / "calibration.yaml");
  const DaemonConfig config =
      DaemonConfig::parse(daemonYaml(tmp.path() / "calibration.yaml", "YUYV"), "test.yaml", tmp.path());
  auto fake = renderedCamera();
  // Pulled out after frame 4 (virtual time); back on the third reopen attempt. The content
  // goes on where it was, so all kFrames rendered frames still arrive.
  fake->scheduleUnplug(fake->now() + 6 * 33'333'333 - 10'000'000);
  fake->replugAfterFailedOpens(2);
  Bus bus;
  daemon::DaemonStats stats;
  {
    daemon::DaemonOptions options = losslessOptions();
    options.capture.reconnect_initial = 100ms;  // attempts after 100, +200, +400 ms
    options.capture.reconnect_max = 2000ms;
    daemon::Daemon d(config, stderr, std::make_unique<V4l2Source>(daemon::v4l2Options(config.source), fake.get()),
                     std::make_unique<testing::SharedLcmSink>(bus.lcm), options);
    bus.run(d, kFrames, 120s);
    stats = d.stats();
  }
  EXPECT_TRUE(fake->violations().empty()) << ::testing::PrintToString(fake->violations());
  EXPECT_EQ(fake->openFdCount(), 0);
  EXPECT_EQ(fake->mappingCount(), 0);
  EXPECT_EQ(fake->streamOnCount(), 2);
  // One policy: the start-up open, two refused re-opens and the one that worked, all by the
  // capture loop; the driver never retried behind it.
  EXPECT_EQ(fake->openAttempts().size(), 4u);

  // The outage is one source failure; every frame is counted once.
  EXPECT_EQ(stats.source_failures, 1);
  ASSERT_FALSE(bus.statuses.empty());
  const status_t& last = bus.statuses.back();
  EXPECT_TRUE(last.final);
  EXPECT_EQ(last.source_failures, 1);
  EXPECT_EQ(last.frames_received, kFrames) << "no frame counted for the time away";
  EXPECT_EQ(last.frames_received,
            last.frames_processed + last.frames_skipped_stale + last.frames_bad +
                last.frames_lost_upstream);
  EXPECT_EQ(last.frames_processed, kFrames);
  bool saw_reconnecting = false;
  for (const status_t& s : bus.statuses)
    if (s.source_state == status_t::SOURCE_RECONNECTING) {
      saw_reconnecting = true;
      EXPECT_THAT(s.last_error, HasSubstr("/dev/video-omnipose-fake"));
    }
  EXPECT_TRUE(saw_reconnecting) << "status showed the outage";

  // Poses resume: sequence numbers keep increasing across the reconnect; the first frame
  // after it is a gap, bridged against the keyframe (the chain stays in segment 0), and
  // every pose but the first matches the ground truth.
  ASSERT_EQ(bus.poses.size(), static_cast<std::size_t>(kFrames));
  int lost_after_start = 0, bridged = 0;
  for (std::size_t k = 1; k < bus.poses.size(); ++k) {
    EXPECT_GT(bus.poses[k].sequence, bus.poses[k - 1].sequence);
    if (bus.poses[k].status == pose_t::STATUS_LOST) ++lost_after_start;
    if (bus.poses[k].track_state == pose_t::TRACK_BRIDGED) ++bridged;
  }
  EXPECT_EQ(lost_after_start, 0);
  EXPECT_EQ(bridged, 1) << "exactly the reconnect is a gap";
  EXPECT_EQ(bus.poses.back().segment, 0) << "the reconnect was bridged";
  int ok = 0;
  expectPosesMatchGroundTruth(bus.poses, *fake, 0.01, &ok);
  EXPECT_EQ(ok, kFrames - 1) << "all but the first frame";
}

// The same policy on the libcamera path: the camera leaves mid-stream (its `disconnected`
// signal), the capture loop closes the source and re-opens it with its back-off until the
// camera is back. Frames come from the fake's own thread in real time, as on a robot.
TEST(DaemonOnFakeLibcameraUnplug, CameraVanishingMidStreamIsReopenedByTheCaptureLoopAndCountedOnce) {
  testing::TempDir tmp("v4l2");
  Calibration{}.save(tmp.path() / "calibration.yaml");
  const DaemonConfig config = DaemonConfig::parse(
      "source: {type: file, path: /nonexistent}\ncalibration: " +
          (tmp.path() / "calibration.yaml").string() + "\nlcm: {url: 'memq://', status_hz: 20}\n",
      "test.yaml", tmp.path());  // the source is replaced below
  const cv::Size size = omniSize();
  auto manager = std::make_shared<testing::FakeCameraManager>();
  testing::FakeCameraConfig camera;
  camera.sizes = {size};
  camera.formats = {testing::kFakeYUYV};
  manager->plug(camera);
  LibcameraOptions o;
  o.camera = "0";
  o.width = size.width;
  o.height = size.height;
  o.fps = 30;
  o.format = "YUYV";
  daemon::DaemonOptions options;
  options.capture.reconnect_initial = 20ms;
  options.capture.reconnect_max = 80ms;

  Bus bus;
  daemon::DaemonStats stats;
  std::size_t poses_at_replug = 0;
  std::size_t opens_at_unplug = 0;
  std::size_t opens_at_replug = 0;
  {
    daemon::Daemon d(config, stderr,
                     std::make_unique<LibcameraSource>(o, testing::FakeCameraManager::opener(manager)),
                     std::make_unique<testing::SharedLcmSink>(bus.lcm), options);
    manager->startFreeRunning(camera.id, 30ms);
    d.start();
    enum class Phase { kStreaming, kUnplugged, kReplugged, kDone } phase = Phase::kStreaming;
    const auto deadline = std::chrono::steady_clock::now() + 90s;
    while (phase != Phase::kDone && std::chrono::steady_clock::now() < deadline) {
      std::this_thread::sleep_for(5ms);
      bus.drain();
      const bool reconnecting_seen =
          !bus.statuses.empty() && bus.statuses.back().source_state == status_t::SOURCE_RECONNECTING;
      if (phase == Phase::kStreaming && bus.poses.size() >= 4) {
        opens_at_unplug = manager->openAttempts().size();
        manager->unplug(camera.id);
        phase = Phase::kUnplugged;
      } else if (phase == Phase::kUnplugged && reconnecting_seen &&
                 manager->openAttempts().size() >= opens_at_unplug + 2 &&
                 nothingInFlight(bus.statuses.back(), bus.poses.size())) {
        // Seen in the status, at least two re-open attempts refused, and every frame from
        // before the unplug processed and its pose received (a loaded machine, a sanitizer,
        // can still be working on one): the camera returns.
        opens_at_replug = manager->openAttempts().size();
        poses_at_replug = bus.poses.size();
        manager->replug(camera.id);
        phase = Phase::kReplugged;
      } else if (phase == Phase::kReplugged && bus.poses.size() >= poses_at_replug + 4) {
        phase = Phase::kDone;
      }
    }
    EXPECT_EQ(phase, Phase::kDone) << "the daemon did not get through the outage in time";
    d.requestStop();
    d.join();
    bus.drain();
    stats = d.stats();
  }
  manager->stopFreeRunning();
  const auto violations = manager->violations();
  EXPECT_TRUE(violations.empty()) << ::testing::PrintToString(violations);
  EXPECT_EQ(testing::FakeCameraManager::memfdMappings(), 0) << "every buffer unmapped";

  // One outage, one source failure; the source itself never retried (every cameras() call
  // between the unplug and the replug is one of the capture loop's attempts, at its pace).
  EXPECT_EQ(stats.source_failures, 1);
  EXPECT_GE(opens_at_replug - opens_at_unplug, 2u);
  EXPECT_LE(opens_at_replug - opens_at_unplug, 40u) << "bounded back-off, not a busy loop";
  ASSERT_FALSE(bus.statuses.empty());
  const status_t& last = bus.statuses.back();
  EXPECT_TRUE(last.final);
  EXPECT_EQ(last.source_failures, 1);
  EXPECT_EQ(last.frames_received, last.frames_processed + last.frames_skipped_stale +
                                      last.frames_bad + last.frames_lost_upstream)
      << "every frame counted once";
  EXPECT_EQ(last.frames_processed, static_cast<std::int64_t>(bus.poses.size()));
  // Poses resumed after the replug, the first of them across the gap: bridged against the
  // keyframe, or (if the fake's view moved too far) a new segment.
  ASSERT_GT(bus.poses.size(), poses_at_replug);
  const pose_t& first_back = bus.poses[poses_at_replug];
  EXPECT_TRUE(first_back.track_state == pose_t::TRACK_BRIDGED ||
              first_back.track_state == pose_t::TRACK_LOST)
      << static_cast<int>(first_back.track_state);
  EXPECT_EQ(first_back.reference_sequence,
            first_back.track_state == pose_t::TRACK_BRIDGED
                ? bus.poses[poses_at_replug - 1].sequence
                : -1);
  EXPECT_GT(first_back.sequence, bus.poses[poses_at_replug - 1].sequence);
}

// ---------------------------------------------------------------------------------------
// Factory and start-up errors (the real kernel behind the source)
// ---------------------------------------------------------------------------------------

TEST(CameraSourceFactory, BuildsV4l2AndReportsEveryBadKey) {
  SourceConfig c;
  c.type = SourceConfig::Type::kV4l2;
  c.device = "/dev/video3";
  c.width = 640;
  c.height = 480;
  c.format = "MJPG";
  auto source = daemon::makeFrameSource(c, {omniSize(), {}, {}});
  ASSERT_NE(source, nullptr);
  EXPECT_THAT(source->describe(), HasSubstr("v4l2 /dev/video3"));

  c.format = "RGB3";
  c.fps = 0;
  try {
    daemon::makeFrameSource(c, {omniSize(), {}, {}});
    ADD_FAILURE() << "expected an error";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("source.format: 'RGB3'"));
    EXPECT_THAT(e.what(), HasSubstr("source.fps"));
  }
}

TEST(CameraSourceFactory, MapsTheSourceSectionToEachDriversOptions) {
  SourceConfig c;
  c.type = SourceConfig::Type::kV4l2;
  c.device = "/dev/video3";
  c.camera = "/base/soc/i2c0mux/i2c@1/imx219@10";
  c.width = 800;
  c.height = 600;
  c.fps = 12.5;
  c.format = "MJPG";
  // The stream settings both sources share, each copied from daemon.yaml.
  const auto expectStreamSettings = [](const auto& o) {
    EXPECT_EQ(o.width, 800);
    EXPECT_EQ(o.height, 600);
    EXPECT_EQ(o.fps, 12.5);
    EXPECT_EQ(o.format, "MJPG");
  };
  const V4l2Options v = daemon::v4l2Options(c);
  EXPECT_EQ(v.device, "/dev/video3");
  expectStreamSettings(v);
  const V4l2Options defaults;
  EXPECT_EQ(v.buffer_count, defaults.buffer_count) << "tuning is not in daemon.yaml";
  EXPECT_EQ(v.clock_resync, defaults.clock_resync);
  EXPECT_EQ(v.drop_stale, defaults.drop_stale);
#if defined(OMNIPOSE_HAVE_LIBCAMERA)
  c.type = SourceConfig::Type::kLibcamera;
  const LibcameraOptions l = daemon::libcameraOptions(c);
  EXPECT_EQ(l.camera, "/base/soc/i2c0mux/i2c@1/imx219@10");
  expectStreamSettings(l);
  EXPECT_EQ(l.buffer_count, LibcameraOptions{}.buffer_count);
#endif
}

TEST(CameraSourceFactory, CheckSourceOptionsListsEveryProblemWithoutOpeningAnything) {
  SourceConfig c;
  c.type = SourceConfig::Type::kV4l2;
  c.device = "/dev/video-omnipose-missing";  // valid as an option; never opened here
  EXPECT_TRUE(daemon::checkSourceOptions(c).empty());

  c.width = 0;
  c.fps = std::nan("");
  c.format = "XYZ";
  const auto problems = daemon::checkSourceOptions(c);
  ASSERT_EQ(problems.size(), 3u) << ::testing::PrintToString(problems);
  EXPECT_EQ(problems[0], "source.width: must be in [1, 16384], is 0");
  EXPECT_EQ(problems[1], "source.fps: must be in (0, 1000]");
  EXPECT_EQ(problems[2],
            "source.format: 'XYZ' is not a V4L2 format this source converts (GREY, YUYV, MJPG)");
  // makeFrameSource() refuses the same section with the same list.
  try {
    daemon::makeFrameSource(c, {omniSize(), {}, {}});
    ADD_FAILURE() << "expected an error";
  } catch (const std::runtime_error& e) {
    for (const auto& p : problems)
      EXPECT_THAT(e.what(), HasSubstr(p));
  }

  c.type = SourceConfig::Type::kLibcamera;
  c.camera = "";
#if defined(OMNIPOSE_HAVE_LIBCAMERA)
  const auto lp = daemon::checkSourceOptions(c);
  ASSERT_EQ(lp.size(), 4u) << ::testing::PrintToString(lp);
  EXPECT_EQ(lp[0].rfind("source.camera: ", 0), 0u) << lp[0];
  EXPECT_EQ(lp[1], "source.width: must be in [1, 16384], is 0");
  EXPECT_EQ(lp[2], "source.fps: must be in (0, 1000]");
  EXPECT_EQ(lp[3].rfind("source.format: 'XYZ'", 0), 0u) << lp[3];
#else
  const auto lp = daemon::checkSourceOptions(c);
  ASSERT_EQ(lp.size(), 1u);
  EXPECT_THAT(lp[0], HasSubstr("source.type: 'libcamera' is not built into this daemon"));
#endif

  c.type = SourceConfig::Type::kFile;  // no driver options; the directory is checked elsewhere
  EXPECT_TRUE(daemon::checkSourceOptions(c).empty());
}

TEST(CameraSourceFactory, LibcameraIsBuiltWhenFound) {
  SourceConfig c;
  c.type = SourceConfig::Type::kLibcamera;
  c.camera = "0";
#if defined(OMNIPOSE_HAVE_LIBCAMERA)
  auto source = daemon::makeFrameSource(c, {omniSize(), {}, {}});
  ASSERT_NE(source, nullptr);
  EXPECT_THAT(source->describe(), HasSubstr("libcamera camera 0"));
#else
  try {
    daemon::makeFrameSource(c, {omniSize(), {}, {}});
    ADD_FAILURE() << "expected 'not built into this daemon'";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("not built into this daemon"));
  }
#endif
}

TEST(DaemonStartup, MissingV4l2DeviceIsAClearErrorNamingIt) {
  testing::TempDir tmp("v4l2");
  Calibration{}.save(tmp.path() / "calibration.yaml");
  const DaemonConfig config = DaemonConfig::parse(
      daemonYaml(tmp.path() / "calibration.yaml", "YUYV", "/dev/video-omnipose-missing"),
      "test.yaml", tmp.path());
  lcm::LCM lcm("memq://");
  try {
    daemon::Daemon d(config, stderr, nullptr, std::make_unique<testing::SharedLcmSink>(lcm));
    ADD_FAILURE() << "expected a start-up error";
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_THAT(what, HasSubstr("/dev/video-omnipose-missing"));
    EXPECT_THAT(what, HasSubstr("no such device"));
  }
}


TEST(DaemonStartup, ASecondDaemonOnTheSameCameraIsRefusedWithTheHoldersPid) {
  testing::TempDir tmp("v4l2");
  Calibration{}.save(tmp.path() / "calibration.yaml");
  // A node the lock can take (the fake serves any path); a symbolic link to it is the same
  // camera, as /dev/v4l/by-id/... is /dev/video0.
  const fs::path node = tmp.path() / "video7";
  std::ofstream(node).close();
  fs::create_symlink(node, tmp.path() / "by-id");
  const auto configFor = [&](const fs::path& device) {
    return DaemonConfig::parse(daemonYaml(tmp.path() / "calibration.yaml", "YUYV", device.string()),
                               "test.yaml", tmp.path());
  };
  const auto fakeAt = [](const fs::path& device) {
    FakeV4l2Device::Config fc;
    fc.path = device.string();
    return std::make_unique<FakeV4l2Device>(fc);
  };
  lcm::LCM lcm("memq://");
  const DaemonConfig first_config = configFor(node);
  auto first_fake = fakeAt(node);
  daemon::Daemon first(first_config, stderr,
                       std::make_unique<V4l2Source>(daemon::v4l2Options(first_config.source), first_fake.get()),
                       std::make_unique<testing::SharedLcmSink>(lcm));
  for (const fs::path& device : {node, tmp.path() / "by-id"}) {
    SCOPED_TRACE(device);
    const DaemonConfig config = configFor(device);
    auto fake = fakeAt(device);
    try {
      daemon::Daemon second(config, stderr,
                            std::make_unique<V4l2Source>(daemon::v4l2Options(config.source), fake.get()),
                            std::make_unique<testing::SharedLcmSink>(lcm));
      ADD_FAILURE() << "a second daemon started on the camera";
    } catch (const std::runtime_error& e) {
      const std::string what = e.what();
      EXPECT_THAT(what,
                  HasSubstr("source: v4l2 " + device.string() + " is in use by another omniposed"));
      EXPECT_THAT(what, HasSubstr("held by process " + std::to_string(::getpid())));
    }
    EXPECT_TRUE(fake->openAttempts().empty()) << "the refused daemon never opened the camera";
  }
}

}  // namespace
}  // namespace omnipose
