// The libcamera source's streaming path, through its FrameSource interface (open / next /
// close, as the daemon's capture loop calls it), on a fake libcamera that behaves as 0.0.3
// does (fake_libcamera.hpp): format and size negotiation, strides, pixels, the newest-frame
// policy, sequence gaps, SensorTimestamp and the clock offset, unplug (the camera released,
// the owner re-opens) and replug, stop with requests in flight.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cerrno>
#include <cmath>
#include <limits>
#include <thread>

#include "fake_libcamera.hpp"
#include "libcamera/libcamera_source.hpp"

using ::testing::HasSubstr;

namespace omnipose {
namespace {

using namespace std::chrono_literals;
using testing::FakeCamera;
using testing::FakeCameraConfig;
using testing::FakeCameraManager;
using testing::kFakeNV12;
using testing::kFakeR8;
using testing::kFakeXRGB;
using testing::kFakeYUYV;

constexpr std::int64_t kMs = 1'000'000;

class LibcameraStreamTest : public ::testing::Test {
 protected:
  void SetUp() override { camera_ = manager_->plug(config_); }
  void TearDown() override {
    const auto v = manager_->violations();
    EXPECT_TRUE(v.empty()) << ::testing::PrintToString(v);
  }

  /// Replaces the plugged camera by one with `config`.
  void replugWith(FakeCameraConfig config) {
    manager_->unplug(config_.id);
    config_ = std::move(config);
    camera_ = manager_->plug(config_);
  }

  LibcameraOptions options(const char* format = "YUYV", int width = 640, int height = 480) {
    LibcameraOptions o;
    o.camera = "0";
    o.width = width;
    o.height = height;
    o.fps = 30;
    o.format = format;
    return o;
  }
  std::unique_ptr<LibcameraSource> source(const LibcameraOptions& o) {
    return std::make_unique<LibcameraSource>(o, FakeCameraManager::opener(manager_));
  }
  void produce(int frames) { manager_->produce(config_.id, frames); }
  /// Produces `frames` frames, then asks `source` for the next one (into out_).
  Expected<FrameInfo> nextAfter(LibcameraSource& source, int frames) {
    produce(frames);
    return source.next(out_, 1000ms);
  }
  std::shared_ptr<FakeCamera> current() const { return manager_->camera(config_.id); }

  /// The content index of the frame delivered at `capture_time_us`.
  std::int64_t contentOf(std::int64_t capture_time_us) const {
    const std::int64_t boottime_ns = capture_time_us * 1000 - manager_->realtimeOffsetNs();
    // capture_time_us is rounded to the microsecond: look around it.
    for (std::int64_t d = -1000; d <= 1000; ++d)
      if (const auto i = manager_->contentIndexAt(boottime_ns + d); i >= 0) return i;
    return -1;
  }

  std::shared_ptr<FakeCameraManager> manager_ = std::make_shared<FakeCameraManager>();
  /// What next() fills: a frame of the default size, 640 x 480.
  cv::Mat out_ = cv::Mat(480, 640, CV_8UC1);
  FakeCameraConfig config_;
  std::shared_ptr<FakeCamera> camera_;
};

// ---- format, size and stride ------------------------------------------------------------

TEST_F(LibcameraStreamTest, YuyvWithPaddedStrideDeliversLumaPixelForPixel) {
  FakeCameraConfig c;
  c.stride_align = 512;  // 640 * 2 = 1280 -> 1536 bytes a row
  replugWith(c);
  auto s = source(options("YUYV"));
  ASSERT_TRUE(s->open()) << s->describe();
  EXPECT_EQ(camera_->configured().fourcc, kFakeYUYV);
  EXPECT_EQ(camera_->configured().stride, 1536u);
  EXPECT_EQ(s->frameSize(), cv::Size(640, 480));
  auto f = nextAfter(*s, 1);
  ASSERT_TRUE(f) << f.error().message();
  EXPECT_EQ(cv::norm(out_, FakeCameraManager::expectedGrey(0, {640, 480}), cv::NORM_INF), 0.0);
  EXPECT_EQ(f->sequence, 0u);
  EXPECT_EQ(s->stats().delivered, 1u);
}

TEST_F(LibcameraStreamTest, Nv12LumaPlaneWithStrideAndChromaInTheSameBuffer) {
  FakeCameraConfig c;
  c.stride_align = 256;  // 640 -> 768 bytes a row
  replugWith(c);
  auto s = source(options("NV12"));
  ASSERT_TRUE(s->open());
  EXPECT_EQ(camera_->configured().fourcc, kFakeNV12);
  EXPECT_EQ(camera_->configured().stride, 768u);
  EXPECT_EQ(camera_->configured().frame_size, 768u * 480 * 3 / 2);
  auto f = nextAfter(*s, 1);
  ASSERT_TRUE(f) << f.error().message();
  EXPECT_EQ(cv::norm(out_, FakeCameraManager::expectedGrey(0, {640, 480}), cv::NORM_INF), 0.0);
}

TEST_F(LibcameraStreamTest, GreyR8CopiedRowByRowPastThePadding) {
  FakeCameraConfig c;
  c.formats = {kFakeR8, kFakeYUYV};
  c.sizes = {{300, 200}};
  c.stride_align = 64;  // 300 -> 320
  replugWith(c);
  auto s = source(options("GREY", 300, 200));
  ASSERT_TRUE(s->open());
  EXPECT_EQ(camera_->configured().fourcc, kFakeR8);
  EXPECT_EQ(camera_->configured().stride, 320u);
  produce(1);
  cv::Mat out(200, 300, CV_8UC1);
  ASSERT_TRUE(s->next(out, 1000ms));
  EXPECT_EQ(cv::norm(out, FakeCameraManager::expectedGrey(0, {300, 200}), cv::NORM_INF), 0.0);
}

TEST_F(LibcameraStreamTest, SizeAdjustedToTheNearestSupportedAndReadBack) {
  auto s = source(options("YUYV", 700, 500));
  ASSERT_TRUE(s->open());
  EXPECT_EQ(s->frameSize(), cv::Size(640, 480));
  EXPECT_THAT(s->describe(), HasSubstr("asked 700x500"));
  produce(1);
  ASSERT_TRUE(s->next(out_, 1000ms));
  EXPECT_EQ(cv::norm(out_, FakeCameraManager::expectedGrey(0, {640, 480}), cv::NORM_INF), 0.0);
}

TEST_F(LibcameraStreamTest, FormatNotOfferedIsReplacedByTheBestOffered) {
  auto s = source(options("GREY"));  // the camera offers XR24, NV12, YUYV
  ASSERT_TRUE(s->open());
  EXPECT_EQ(camera_->configured().fourcc, kFakeNV12);
  EXPECT_THAT(s->describe(), HasSubstr("NV12"));
  EXPECT_THAT(s->describe(), HasSubstr("(GREY not offered)"));
  auto a = source(options("auto"));
  s->close();
  ASSERT_TRUE(a->open());
  EXPECT_EQ(current()->configured().fourcc, kFakeNV12);
}

TEST_F(LibcameraStreamTest, NothingConvertibleOrInvalidConfigurationReleasesTheCamera) {
  FakeCameraConfig c;
  c.formats = {kFakeXRGB};
  replugWith(c);
  auto s = source(options("auto"));
  auto r = s->open();
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code(), ErrorCode::kUnsupportedFormat);
  EXPECT_FALSE(camera_->acquired());

  replugWith(FakeCameraConfig{});
  manager_->rejectConfigurations(true);
  r = s->open();
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code(), ErrorCode::kUnsupportedFormat);
  EXPECT_THAT(r.error().message(), HasSubstr("rejects NV12 640x480"));
  EXPECT_FALSE(camera_->acquired());
  manager_->rejectConfigurations(false);
  EXPECT_TRUE(s->open());
}

TEST_F(LibcameraStreamTest, CameraChoiceBusyMissingAndById) {
  manager_->setBusy(true);
  auto s = source(options());
  auto r = s->open();
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code(), ErrorCode::kBusy);
  manager_->setBusy(false);

  LibcameraOptions o = options();
  o.camera = "imx477";
  r = source(o)->open();
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code(), ErrorCode::kNotFound);
  o.camera = "1";
  r = source(o)->open();
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code(), ErrorCode::kNoDevice);

  o.camera = config_.id;
  auto by_id = source(o);
  ASSERT_TRUE(by_id->open());
  EXPECT_THAT(by_id->describe(), HasSubstr(config_.id));
  EXPECT_TRUE(camera_->running());

  // A second source on the same camera: libcamera's acquire() refuses it.
  r = source(options())->open();
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code(), ErrorCode::kBusy);
}

TEST_F(LibcameraStreamTest, FrameRateSetsFrameDurationLimitsWhereSettable) {
  LibcameraOptions o = options();
  o.fps = 25;
  auto s = source(o);
  ASSERT_TRUE(s->open());
  EXPECT_EQ(camera_->frameDurationUs(), 40000);
  EXPECT_THAT(s->describe(), HasSubstr("25 fps"));
  s->close();

  FakeCameraConfig c;
  c.frame_duration_settable = false;
  replugWith(c);
  ASSERT_TRUE(s->open());
  EXPECT_EQ(camera_->frameDurationUs(), 0);
  EXPECT_THAT(s->describe(), HasSubstr("frame rate not settable"));
}

// ---- newest frame, stale and lost frames -------------------------------------------------

TEST_F(LibcameraStreamTest, NewestFrameIsDeliveredAndTheStaleOnesRequeued) {
  auto s = source(options());
  ASSERT_TRUE(s->open());
  auto f = nextAfter(*s, 3);  // 4 requests queued: 3 complete, one still waits
  ASSERT_TRUE(f);
  EXPECT_EQ(f->sequence, 2u);
  EXPECT_EQ(contentOf(f->capture_time_us), 2);
  EXPECT_EQ(cv::norm(out_, FakeCameraManager::expectedGrey(2, {640, 480}), cv::NORM_INF), 0.0);
  EXPECT_EQ(s->stats().stale_dropped, 2u);
  EXPECT_EQ(camera_->pendingRequests(), 4) << "every request is back with the camera";
}

TEST_F(LibcameraStreamTest, WhenEveryRequestHadCompletedAFreshFrameIsAwaited) {
  auto s = source(options());
  ASSERT_TRUE(s->open());
  produce(6);  // 4 complete, then 2 frames find no request: lost
  auto f = s->next(out_, 30ms);
  ASSERT_FALSE(f);
  EXPECT_EQ(f.error().code(), ErrorCode::kTimeout);
  EXPECT_EQ(s->stats().stale_dropped, 4u);
  EXPECT_EQ(camera_->pendingRequests(), 4);
  f = nextAfter(*s, 1);
  ASSERT_TRUE(f);
  EXPECT_EQ(contentOf(f->capture_time_us), 6);
  EXPECT_EQ(f->sequence, 6u);
  EXPECT_EQ(s->stats().lost_upstream, 2u) << "sequence 4 and 5 never reached the source";
}

TEST_F(LibcameraStreamTest, WithoutDropStaleTheNewestCompletedFrameIsDelivered) {
  LibcameraOptions o = options();
  o.drop_stale = false;
  auto s = source(o);
  ASSERT_TRUE(s->open());
  auto f = nextAfter(*s, 4);
  ASSERT_TRUE(f);
  EXPECT_EQ(f->sequence, 3u);
  EXPECT_EQ(s->stats().stale_dropped, 3u);
}

TEST_F(LibcameraStreamTest, SensorDroppedFramesAreSequenceGaps) {
  auto s = source(options());
  ASSERT_TRUE(s->open());
  auto f = nextAfter(*s, 1);
  ASSERT_TRUE(f);
  EXPECT_EQ(f->sequence, 0u);
  manager_->skipFrames(3);
  f = nextAfter(*s, 1);
  ASSERT_TRUE(f);
  EXPECT_EQ(f->sequence, 4u);
  EXPECT_EQ(s->stats().lost_upstream, 3u);
  EXPECT_EQ(s->stats().delivered, 2u);
}

TEST_F(LibcameraStreamTest, ErrorFramesAreDroppedAndCounted) {
  auto s = source(options());
  ASSERT_TRUE(s->open());
  manager_->flagError(1);
  auto f = nextAfter(*s, 2);
  ASSERT_TRUE(f);
  EXPECT_EQ(contentOf(f->capture_time_us), 0) << "the newest good frame";
  EXPECT_EQ(s->stats().error_frames, 1u);
  manager_->flagError(2);
  f = nextAfter(*s, 1);
  ASSERT_FALSE(f);
  EXPECT_EQ(f.error().code(), ErrorCode::kBadFrame);
  f = nextAfter(*s, 1);
  ASSERT_TRUE(f) << "streaming goes on";
  EXPECT_EQ(contentOf(f->capture_time_us), 3);
  EXPECT_EQ(camera_->pendingRequests(), 4);
}

// ---- timestamps ---------------------------------------------------------------------------

TEST_F(LibcameraStreamTest, SensorTimestampBecomesWallClockMicroseconds) {
  auto s = source(options());
  ASSERT_TRUE(s->open());
  for (int i = 0; i < 3; ++i) {
    auto f = nextAfter(*s, 1);
    ASSERT_TRUE(f);
    EXPECT_EQ(contentOf(f->capture_time_us), i);
    const std::int64_t error = f->capture_time_us * 1000 - manager_->realtimeOffsetNs() -
                               manager_->boottimeOf(static_cast<std::uint64_t>(i));
    EXPECT_LE(std::abs(error), 500)
        << "capture time = SensorTimestamp (boottime) + the measured offset, to the microsecond";
    // On CLOCK_MONOTONIC: boottime less the time the system was suspended (120 s here).
    const std::int64_t steady_error =
        f->steady_time_us * 1000 -
        (manager_->boottimeOf(static_cast<std::uint64_t>(i)) - manager_->boottimeOffsetNs());
    EXPECT_LE(std::abs(steady_error), 1000);
  }
}

TEST_F(LibcameraStreamTest, TheReportedExposureGoesOnAndMovesTheStampToTheCaptureTime) {
  // A camera that stamps the start of its first row's readout (the end of its exposure) and
  // reports each frame's ExposureTime: every stamp moved back by half that frame's exposure.
  FakeCameraConfig c;
  c.exposure_time_us = {4000, 16000, 9000};
  replugWith(c);
  LibcameraOptions o = options();
  o.sensor.stamped_at = StampedAt::kExposureEnd;
  o.sensor.exposure_s = 0.03;  // the calibration's, not used: each frame states its own
  auto s = source(o);
  ASSERT_TRUE(s->open());
  for (int i = 0; i < 3; ++i) {
    auto f = nextAfter(*s, 1);
    ASSERT_TRUE(f);
    const double exposure_us = c.exposure_time_us[static_cast<std::size_t>(i)];
    EXPECT_DOUBLE_EQ(f->exposure_s, 1e-6 * exposure_us);
    const std::int64_t error = f->capture_time_us * 1000 - manager_->realtimeOffsetNs() -
                               manager_->boottimeOf(static_cast<std::uint64_t>(i)) +
                               static_cast<std::int64_t>(500.0 * exposure_us);
    EXPECT_LE(std::abs(error), 500) << "frame " << i;
    const std::int64_t steady_error =
        f->steady_time_us * 1000 -
        (manager_->boottimeOf(static_cast<std::uint64_t>(i)) - manager_->boottimeOffsetNs() -
         static_cast<std::int64_t>(500.0 * exposure_us));
    EXPECT_LE(std::abs(steady_error), 1000) << "frame " << i;
  }
}

TEST_F(LibcameraStreamTest, WithoutAReportedExposureTheCalibrationsMovesTheStamp) {
  LibcameraOptions o = options();
  o.sensor.stamped_at = StampedAt::kExposureStart;
  o.sensor.exposure_s = 0.01;
  auto s = source(o);
  ASSERT_TRUE(s->open());
  auto f = nextAfter(*s, 1);
  ASSERT_TRUE(f);
  EXPECT_TRUE(std::isnan(f->exposure_s)) << "not reported";
  const std::int64_t error = f->capture_time_us * 1000 - manager_->realtimeOffsetNs() -
                             manager_->boottimeOf(0) - 5 * kMs;
  EXPECT_LE(std::abs(error), 500) << "moved on by half the calibration's 10 ms";
}

TEST_F(LibcameraStreamTest, BufferTimestampWhenSensorTimestampIsAbsent) {
  FakeCameraConfig c;
  c.sensor_timestamp = false;
  replugWith(c);
  auto s = source(options());
  ASSERT_TRUE(s->open());
  auto f = nextAfter(*s, 1);
  ASSERT_TRUE(f);
  EXPECT_EQ(contentOf(f->capture_time_us), 0);
}

TEST_F(LibcameraStreamTest, ClockOffsetTakesTheLeastPreemptedOfClockSamples) {
  const std::int64_t delay = 2 * kMs;
  // The error (ns) of the capture time of frame `frame`, the next one produced, from a source
  // that opened with `samples` clock samples while every `every`-th realtime read stalled.
  const auto captureTimeError = [&](int samples, int every, int frame) -> std::int64_t {
    manager_->delayRealtimeReads(every, delay);
    LibcameraOptions o = options();
    o.clock_samples = samples;
    auto s = source(o);
    EXPECT_TRUE(s->open());
    manager_->delayRealtimeReads(0, 0);
    auto f = nextAfter(*s, 1);
    if (!f) {
      ADD_FAILURE() << f.error().message();
      return std::numeric_limits<std::int64_t>::max();
    }
    s->close();
    return f->capture_time_us * 1000 - manager_->realtimeOffsetNs() - manager_->boottimeOf(frame);
  };
  // One sample, preempted between its reads: the offset is off by half the stall.
  EXPECT_NEAR(static_cast<double>(captureTimeError(1, 1, 0)), static_cast<double>(delay / 2),
              1000.0);
  // Seven samples, every other one preempted: an unpreempted one wins, the offset is exact.
  EXPECT_LE(std::abs(captureTimeError(7, 2, 1)), 500) << "only the rounding to microseconds";
}

TEST_F(LibcameraStreamTest, WallClockStepIsFollowedAfterTheResync) {
  LibcameraOptions o = options();
  o.clock_resync = 1000ms;
  auto s = source(o);
  ASSERT_TRUE(s->open());
  auto before = nextAfter(*s, 1);
  ASSERT_TRUE(before);
  manager_->stepRealtime(5'000 * kMs);  // NTP steps the wall clock 5 s forward
  manager_->advance(1500 * kMs);        // past clock_resync
  auto after = nextAfter(*s, 1);
  ASSERT_TRUE(after);
  EXPECT_EQ(contentOf(after->capture_time_us), 1) << "the new offset is used";
  EXPECT_NEAR(static_cast<double>(after->capture_time_us - before->capture_time_us),
              5'000'000.0 + 1'500'000.0 + 33'333.0, 5.0);
}

// ---- unplug, replug: the owner re-opens ------------------------------------------------

TEST_F(LibcameraStreamTest, UnplugReleasesTheCameraAndReportsDisconnectedUntilReopened) {
  auto s = source(options());
  ASSERT_TRUE(s->open());
  auto first = nextAfter(*s, 1);
  ASSERT_TRUE(first);
  const auto old_camera = camera_;

  manager_->unplug(config_.id);  // disconnected, then its pending requests cancelled
  auto r = s->next(out_, 1000ms);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code(), ErrorCode::kDisconnected);
  EXPECT_EQ(s->stats().disconnects, 1u);
  EXPECT_FALSE(old_camera->acquired()) << "released";
  EXPECT_EQ(old_camera->allocatedBuffers(), 0);
  EXPECT_EQ(FakeCameraManager::memfdMappings(), 0) << "every buffer unmapped";
  EXPECT_THAT(s->describe(), HasSubstr("(disconnected)"));

  // The source does not retry on its own: next() answers at once, asking libcamera nothing.
  const std::size_t opens_before = manager_->openAttempts().size();
  for (int i = 0; i < 3; ++i) {
    r = s->next(out_, 1000ms);
    ASSERT_FALSE(r);
    EXPECT_EQ(r.error().code(), ErrorCode::kDisconnected);
    EXPECT_THAT(r.error().message(), HasSubstr("close() and open()"));
  }
  EXPECT_EQ(manager_->openAttempts().size(), opens_before) << "no reopen attempt";

  // Its owner re-opens: refused while the camera is away, streaming once it is back.
  s->close();
  auto refused = s->open();
  ASSERT_FALSE(refused);
  EXPECT_EQ(refused.error().code(), ErrorCode::kNoDevice) << refused.error().message();
  manager_->advance(3000 * kMs);  // away for a while
  camera_ = manager_->replug(config_.id);
  ASSERT_NE(camera_, old_camera) << "a new camera object under the same id";
  ASSERT_TRUE(s->open());
  EXPECT_TRUE(camera_->running());
  EXPECT_EQ(camera_->pendingRequests(), 4);
  auto resumed = nextAfter(*s, 1);
  ASSERT_TRUE(resumed) << resumed.error().message();
  EXPECT_EQ(cv::norm(out_, FakeCameraManager::expectedGrey(
                              static_cast<std::uint64_t>(contentOf(resumed->capture_time_us)),
                              {640, 480}),
                     cv::NORM_INF),
            0.0);
  const double frames =
      static_cast<double>(resumed->capture_time_us - first->capture_time_us) * 1e-6 * 30.0;
  EXPECT_EQ(resumed->sequence, first->sequence + static_cast<std::uint64_t>(std::llround(frames)))
      << "the time away is a gap of that many frames";
  EXPECT_GT(resumed->sequence, first->sequence + 80);
}

TEST_F(LibcameraStreamTest, CallerCloseAndOpenContinuesTheSequence) {
  auto s = source(options());
  ASSERT_TRUE(s->open());
  auto a = nextAfter(*s, 1);
  ASSERT_TRUE(a);
  s->close();
  EXPECT_FALSE(camera_->acquired());
  manager_->advance(1000 * kMs);
  ASSERT_TRUE(s->open());
  EXPECT_EQ(camera_->startCount(), 2);
  auto b = nextAfter(*s, 1);
  ASSERT_TRUE(b);
  EXPECT_GT(b->sequence, a->sequence + 25) << "a second away is about 31 frames";
  EXPECT_LT(b->sequence, a->sequence + 35);
}

// ---- stop with requests in flight, misuse -------------------------------------------------

TEST_F(LibcameraStreamTest, CloseWithRequestsInFlightCancelsThemAndFreesEverything) {
  auto s = source(options());
  ASSERT_TRUE(s->open());
  EXPECT_GT(FakeCameraManager::memfdMappings(), 0);
  produce(2);  // two completed, waiting for the capture thread; two still queued
  s->close();
  EXPECT_FALSE(camera_->running());
  EXPECT_EQ(camera_->pendingRequests(), 0);
  EXPECT_EQ(camera_->allocatedBuffers(), 0);
  EXPECT_FALSE(camera_->acquired());
  EXPECT_EQ(FakeCameraManager::memfdMappings(), 0);
  auto r = s->next(out_, 10ms);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code(), ErrorCode::kInvalidArgument);
}

TEST_F(LibcameraStreamTest, CloseWhileTheCameraCompletesFromItsThread) {
  int delivered = 0;
  for (int round = 0; round < 20; ++round) {
    auto s = source(options());
    ASSERT_TRUE(s->open());
    manager_->startFreeRunning(config_.id, 200us);
    for (int i = 0; i < 3; ++i)
      if (s->next(out_, 1000ms)) ++delivered;
    s->close();  // completions keep coming from the camera's thread until stop()
    manager_->stopFreeRunning();
    EXPECT_EQ(camera_->pendingRequests(), 0);
    EXPECT_EQ(camera_->allocatedBuffers(), 0);
  }
  EXPECT_EQ(delivered, 60);
  EXPECT_EQ(FakeCameraManager::memfdMappings(), 0);
}

TEST_F(LibcameraStreamTest, UnplugWhileTheCameraCompletesFromItsThread) {
  auto s = source(options());
  ASSERT_TRUE(s->open());
  manager_->startFreeRunning(config_.id, 200us);
  ASSERT_TRUE(s->next(out_, 1000ms));
  manager_->unplug(config_.id);
  auto r = s->next(out_, 1000ms);
  while (r) r = s->next(out_, 1000ms);  // frames completed before the unplug
  EXPECT_EQ(r.error().code(), ErrorCode::kDisconnected);
  manager_->stopFreeRunning();
  EXPECT_EQ(FakeCameraManager::memfdMappings(), 0);
  s->close();
}

TEST_F(LibcameraStreamTest, UnplugWhileNextWaitsFreesTheBuffersOnlyOnceEveryRequestIsBack) {
  // The camera's disconnected signal wakes next() before the camera cancels its pending
  // requests (on its own thread): the source must not free their buffers before they are
  // back (the fake records that as a violation, checked in TearDown).
  manager_->setCancelDelayAfterDisconnect(20ms);
  for (int round = 0; round < 3; ++round) {
    auto s = source(options());
    ASSERT_TRUE(s->open());
    Expected<FrameInfo> r = std::unexpected(Error());
    std::thread capture([&] { r = s->next(out_, 5000ms); });  // waits: nothing is produced
    std::this_thread::sleep_for(2ms);
    manager_->unplug(config_.id);
    capture.join();
    ASSERT_FALSE(r);
    EXPECT_EQ(r.error().code(), ErrorCode::kDisconnected);
    EXPECT_EQ(FakeCameraManager::memfdMappings(), 0);
    s->close();
    camera_ = manager_->replug(config_.id);
  }
}

TEST_F(LibcameraStreamTest, MisuseIsInvalidArgument) {
  auto s = source(options());
  auto r = s->next(out_, 10ms);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code(), ErrorCode::kInvalidArgument);
  ASSERT_TRUE(s->open());
  cv::Mat wrong(100, 100, CV_8UC1);
  r = s->next(wrong, 10ms);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code(), ErrorCode::kInvalidArgument);
  EXPECT_EQ(wrong.size(), cv::Size(100, 100)) << "never reallocated";
  ASSERT_TRUE(s->open()) << "open() on an open source reopens";
  EXPECT_EQ(camera_->startCount(), 2);
}

}  // namespace
}  // namespace omnipose
