// In-process tests of the daemon library: mailbox, statistics (the one table of counters),
// the capture loop's reconnection and back-off, file source, source factory, and whole
// daemon runs over LCM memq:// (one lcm::LCM shared by the daemon's sink and the test's
// subscribers): poses per frame, status, corrupt frames mid-stream, a vanishing dataset
// directory, stale frames, fit diagnostics, start-up failures, publish failures.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <fstream>
#include <functional>
#include <numbers>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "daemon/capture_loop.hpp"
#include "daemon/counters.hpp"
#include "daemon/daemon.hpp"
#include "file/file_frame_source.hpp"
#include "daemon/frame_mailbox.hpp"
#include "daemon/map_keeper.hpp"
#include "daemon/panorama_pictures.hpp"
#include "daemon/sample_ring.hpp"
#include "daemon/source_factory.hpp"
#include "daemon/status_board.hpp"
#include "daemon/wall_clock.hpp"
#include "runtime/worker_pool.hpp"
#include <sys/stat.h>

#include "bad_images.hpp"
#include "daemon_test_support.hpp"
#include "gyro_dataset.hpp"
#include "omnipose/io/gyro.hpp"
#include "daemon/config.hpp"
#include "map/map_file.hpp"
#include "replay.hpp"

using ::testing::HasSubstr;

namespace omnipose {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;
using daemon::Daemon;
using daemon::FrameMailbox;
using daemon::MailboxFrame;
using daemon::SteadyClock;
using testing::TempDir;

constexpr int kFrames = 24;

SteadyClock::time_point SteadyClockNow() { return SteadyClock::now(); }

/// Lossless replay (every frame processed), the rest of DaemonOptions at its defaults.
daemon::DaemonOptions lossless() {
  daemon::DaemonOptions options;
  options.force_lossless = true;
  return options;
}

/// One rendered yaw dataset shared by every test (the renderer is the slow part). Tests
/// that damage a dataset work on a copy.
const fs::path& yawDataset() {
  static const fs::path path = testing::cachedDataset(
      "yaw" + std::to_string(kFrames), [](const fs::path& dir) { testing::renderDataset(dir, "yaw", kFrames); });
  return path;
}

cv::Size omniSize() { return {Calibration{}.omni.image_width, Calibration{}.omni.image_height}; }

// ---------------------------------------------------------------------------------------
// Small parts
// ---------------------------------------------------------------------------------------

TEST(SampleRing, NearestRankPercentilesOverTheLastSamples) {
  daemon::SampleRing<100> ring;
  EXPECT_EQ(ring.percentile(0.5), 0.0f);
  for (int i = 1; i <= 100; ++i) ring.add(static_cast<float>(i));
  EXPECT_EQ(ring.percentile(0.5), 50.0f);
  EXPECT_EQ(ring.percentile(0.99), 99.0f);
  EXPECT_EQ(ring.percentile(1.0), 100.0f);
  for (int i = 0; i < 100; ++i) ring.add(1000.0f);  // old samples fall out
  EXPECT_EQ(ring.percentile(0.5), 1000.0f);
  EXPECT_EQ(ring.size(), 100u);
}

FrameInfo infoWithSequence(std::uint64_t s) {
  FrameInfo i;
  i.sequence = s;
  return i;
}

TEST(CountersTable, BoardSnapshotAndStatusCarryEveryCounterUnderItsName) {
  daemon::StatusBoard board(nullptr);
  // A distinct value per counter, set through the table itself.
  std::int64_t k = 0;
  daemon::forEachCounter(board, [&](const char*, std::atomic<std::int64_t>& c) { c += 1000 + 7 * ++k; });
  ASSERT_EQ(k, daemon::kCounterCount);
  board.segment = 3;
  board.setSourceState(daemon::SourceState::kReconnecting);

  const daemon::DaemonStats stats = board.snapshot();
  status_t sent{};
  daemon::fillStatus(stats, sent);
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(sent.getEncodedSize()));
  ASSERT_EQ(sent.encode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));
  status_t got;
  ASSERT_EQ(got.decode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));

  std::vector<std::pair<std::string, std::int64_t>> from_stats, from_status;
  daemon::forEachCounter(stats, [&](const char* label, std::int64_t v) { from_stats.emplace_back(label, v); });
  daemon::forEachCounter(got, [&](const char* label, std::int64_t v) { from_status.emplace_back(label, v); });
  ASSERT_EQ(from_stats.size(), static_cast<std::size_t>(daemon::kCounterCount));
  EXPECT_EQ(from_status, from_stats) << "every counter reaches status_t, under its own field";
  for (std::size_t i = 0; i < from_stats.size(); ++i)
    EXPECT_EQ(from_stats[i].second, 1000 + 7 * static_cast<std::int64_t>(i + 1)) << from_stats[i].first;
  EXPECT_EQ(got.publish_failures, stats.publish_failures);
  EXPECT_EQ(got.frames_skipped_stale, stats.frames_skipped_stale);
  EXPECT_EQ(got.segment, 3);
  EXPECT_EQ(got.source_state, status_t::SOURCE_RECONNECTING);
}

TEST(CountersTable, TheMailboxCountsSkippedFramesIntoTheBoard) {
  daemon::StatusBoard board(nullptr);
  FrameMailbox box({8, 4}, /*lossless=*/false, 3, &board.frames_skipped_stale);
  for (int i = 0; i < 4; ++i) box.post(FrameInfo{});  // three overwritten
  box.requestStop();                                  // the fourth never taken
  EXPECT_EQ(board.frames_skipped_stale.load(), 4);
  EXPECT_EQ(box.skipped(), 4);
  EXPECT_EQ(board.snapshot().frames_skipped_stale, 4);
}

TEST(CaptureBackoff, DoublesUpToTheCapAndStartsOverOnReset) {
  daemon::Backoff b(100ms, 700ms);
  EXPECT_EQ(b.next(), 100ms);
  EXPECT_EQ(b.next(), 200ms);
  EXPECT_EQ(b.next(), 400ms);
  EXPECT_EQ(b.next(), 700ms);
  EXPECT_EQ(b.next(), 700ms) << "bounded";
  b.reset();
  EXPECT_EQ(b.next(), 100ms);
}

TEST(CaptureBackoff, NonsenseBoundsAreClamped) {
  daemon::Backoff zero(0ms, 0ms);  // initial below 1 ms: 1 ms; max below initial: initial
  EXPECT_EQ(zero.next(), 1ms);
  EXPECT_EQ(zero.next(), 1ms);
  daemon::Backoff inverted(300ms, 100ms);
  EXPECT_EQ(inverted.next(), 300ms);
  EXPECT_EQ(inverted.next(), 300ms);
}

TEST(FrameMailbox, ProcessorTakesTheNewestAndOverwrittenFramesCountAsSkipped) {
  FrameMailbox box({8, 4}, /*lossless=*/false);
  for (std::uint64_t s = 0; s < 5; ++s) {
    box.writeBuffer().setTo(static_cast<int>(s));
    EXPECT_EQ(box.post(infoWithSequence(s)), s > 0);  // every earlier one is overwritten
  }
  MailboxFrame f;
  ASSERT_EQ(box.take(SteadyClockNow() + 10ms, f), FrameMailbox::TakeResult::kFrame);
  EXPECT_EQ(f.info.sequence, 4u);
  EXPECT_EQ(f.image->at<uchar>(0, 0), 4);
  EXPECT_EQ(f.skipped_before, 4);
  EXPECT_EQ(box.skipped(), 4);
  EXPECT_EQ(box.posted(), 5);
  // While the processor holds its slot, the capture side never writes into it.
  for (int s = 5; s < 9; ++s) {
    EXPECT_NE(box.writeBuffer().data, f.image->data);
    box.writeBuffer().setTo(s);
    box.post(infoWithSequence(static_cast<std::uint64_t>(s)));
  }
  EXPECT_EQ(f.image->at<uchar>(0, 0), 4);
  box.release();
  ASSERT_EQ(box.take(SteadyClockNow() + 10ms, f), FrameMailbox::TakeResult::kFrame);
  EXPECT_EQ(f.info.sequence, 8u);
  EXPECT_EQ(f.skipped_before, 3);
  box.release();
  EXPECT_EQ(box.take(SteadyClockNow() + 10ms, f), FrameMailbox::TakeResult::kTimeout);
}

TEST(FrameMailbox, GapFlagSurvivesWhenTheFlaggedFrameIsOverwritten) {
  FrameMailbox box({8, 4}, false);
  box.post(infoWithSequence(0));
  MailboxFrame f;
  ASSERT_EQ(box.take(SteadyClockNow() + 10ms, f), FrameMailbox::TakeResult::kFrame);
  EXPECT_FALSE(f.gap_before);
  box.release();
  box.markGap();
  box.post(infoWithSequence(2));  // carries the gap
  box.post(infoWithSequence(3));  // overwrites it: must inherit the gap
  ASSERT_EQ(box.take(SteadyClockNow() + 10ms, f), FrameMailbox::TakeResult::kFrame);
  EXPECT_EQ(f.info.sequence, 3u);
  EXPECT_TRUE(f.gap_before);
  box.release();
  box.post(infoWithSequence(4));
  ASSERT_EQ(box.take(SteadyClockNow() + 10ms, f), FrameMailbox::TakeResult::kFrame);
  EXPECT_FALSE(f.gap_before);
}

TEST(FrameMailbox, LosslessModeWaitsUntilTheProcessorTookTheFrame) {
  FrameMailbox box({8, 4}, /*lossless=*/true);
  EXPECT_TRUE(box.waitUntilTaken(1ms));
  box.post(infoWithSequence(0));
  EXPECT_FALSE(box.waitUntilTaken(20ms));  // not taken yet
  std::thread processor([&] {
    std::this_thread::sleep_for(30ms);
    MailboxFrame f;
    box.take(SteadyClockNow() + 1s, f);
    box.release();
  });
  EXPECT_TRUE(box.waitUntilTaken(2s));
  processor.join();
  EXPECT_EQ(box.skipped(), 0);
}

TEST(FrameMailbox, AFrameNeverTakenBeforeTheStopCountsAsSkipped) {
  FrameMailbox box(cv::Size(8, 8), /*lossless=*/false);
  FrameInfo info;
  info.sequence = 1;
  box.post(info);  // posted, not taken
  box.requestStop();
  EXPECT_EQ(box.skipped(), 1);
  MailboxFrame frame;
  EXPECT_EQ(box.take(std::chrono::steady_clock::now(), frame), FrameMailbox::TakeResult::kClosed);
  info.sequence = 2;
  EXPECT_TRUE(box.post(info)) << "a frame read while stopping is dropped";
  EXPECT_EQ(box.skipped(), 2);
  EXPECT_EQ(box.posted(), 2);
}

TEST(FrameMailbox, CloseDrainsTheLastFrameAndStopWakesEverybody) {
  FrameMailbox box({8, 4}, false);
  box.post(infoWithSequence(7));
  box.close();
  MailboxFrame f;
  ASSERT_EQ(box.take(SteadyClockNow() + 10ms, f), FrameMailbox::TakeResult::kFrame);
  box.release();
  EXPECT_EQ(box.take(SteadyClockNow() + 1s, f), FrameMailbox::TakeResult::kClosed);

  FrameMailbox waiting({8, 4}, false);
  std::thread stopper([&] {
    std::this_thread::sleep_for(30ms);
    waiting.requestStop();
  });
  const auto t0 = SteadyClockNow();
  EXPECT_EQ(waiting.take(t0 + 10s, f), FrameMailbox::TakeResult::kClosed);
  EXPECT_LT(SteadyClockNow() - t0, 5s);
  stopper.join();
}

// ---------------------------------------------------------------------------------------
// File source
// ---------------------------------------------------------------------------------------

FileFrameSource::Options fileOptions(const fs::path& dir, bool realtime, bool loop = false) {
  return {.directory = dir, .calibration = dir / "calibration.yaml", .frame_size = omniSize(),
          .realtime = realtime, .loop = loop};
}

TEST(FileFrameSource, DeliversEveryFrameInOrderAsGreyWithItsTimestamp) {
  const fs::path& data = yawDataset();
  FileFrameSource source(fileOptions(data, /*realtime=*/false));
  ASSERT_TRUE(source.open().has_value());
  EXPECT_EQ(source.frameCount(), kFrames);
  const auto stamps = testing::readTimestamps(data);
  cv::Mat buffer(omniSize(), CV_8UC1);
  const uchar* const data_ptr = buffer.data;
  std::int64_t last_capture = 0;
  for (int i = 0; i < kFrames; ++i) {
    auto got = source.next(buffer, 100ms);
    ASSERT_TRUE(got.has_value()) << got.error().c_str();
    EXPECT_EQ(got->index, i);
    EXPECT_EQ(got->sequence, static_cast<std::uint64_t>(i));
    const std::string name = testing::frameName(i);
    EXPECT_DOUBLE_EQ(got->source_timestamp, stamps.at(name));
    EXPECT_GE(got->capture_time_us, last_capture);
    last_capture = got->capture_time_us;
    EXPECT_EQ(buffer.data, data_ptr) << "the caller's buffer must never be reallocated";
    if (i == 3) {
      const cv::Mat expected = cv::imread((data / "frames" / name).string(), cv::IMREAD_GRAYSCALE);
      EXPECT_EQ(cv::norm(expected, buffer, cv::NORM_INF), 0.0);
    }
  }
  auto end = source.next(buffer, 100ms);
  ASSERT_FALSE(end.has_value());
  EXPECT_EQ(end.error().code(), ErrorCode::kEndOfStream);
}

TEST(FileFrameSource, PassesEachFramesRecordedExposure) {
  TempDir tmp("filesrc-exposure");
  testing::copyDataset(yawDataset(), tmp / "d");
  {
    std::ofstream out(tmp / "d" / "timestamps.txt");
    for (int i = 0; i < kFrames; ++i)
      out << testing::frameName(i) << ' ' << i / 30.0 << (i == 2 ? "" : " 0.00" + std::to_string(i % 9 + 1))
          << '\n';
  }
  FileFrameSource source(fileOptions(tmp / "d", /*realtime=*/false));
  ASSERT_TRUE(source.open().has_value());
  cv::Mat buffer(omniSize(), CV_8UC1);
  for (int i = 0; i < kFrames; ++i) {
    auto got = source.next(buffer, 100ms);
    ASSERT_TRUE(got.has_value()) << got.error().c_str();
    if (i == 2)
      EXPECT_TRUE(std::isnan(got->exposure_s)) << "none recorded";
    else
      EXPECT_DOUBLE_EQ(got->exposure_s, 0.001 * (i % 9 + 1)) << "frame " << i;
  }
}

TEST(FileFrameSource, RealtimeDeliversAtTheRecordedIntervals) {
  TempDir tmp("filesrc-rt");
  testing::copyDataset(yawDataset(), tmp / "d");
  testing::writeTimestamps(tmp / "d", kFrames, [](int i) { return 100.0 + 0.025 * i; });  // 25 ms
  FileFrameSource source(fileOptions(tmp / "d", /*realtime=*/true));
  ASSERT_TRUE(source.open().has_value());
  cv::Mat buffer(omniSize(), CV_8UC1);
  std::vector<std::int64_t> capture;
  const auto t0 = SteadyClockNow();
  while (capture.size() < 8) {
    auto got = source.next(buffer, 10ms);
    if (!got) {
      ASSERT_EQ(got.error().code(), ErrorCode::kTimeout) << got.error().c_str();
      continue;
    }
    capture.push_back(got->capture_time_us);
    // Never delivered before its due time.
    EXPECT_LE(got->capture_time_us, daemon::wallClockMicros());
  }
  const double elapsed = std::chrono::duration<double>(SteadyClockNow() - t0).count();
  EXPECT_GE(elapsed, 7 * 0.025 - 0.002);
  for (std::size_t i = 1; i < capture.size(); ++i) {
    EXPECT_NEAR(capture[i] - capture[i - 1], 25000, 2) << "capture stamps follow the recording";
  }
}

TEST(FileFrameSource, CorruptAndWrongSizeFramesAreBadFramesNamingTheFile) {
  TempDir tmp("filesrc-bad");
  testing::copyDataset(yawDataset(), tmp / "d");
  testing::writeText(tmp / "d/frames/000002.png", "this is not a PNG file");
  cv::imwrite((tmp / "d/frames/000004.png").string(), cv::Mat(100, 120, CV_8UC1, cv::Scalar(90)));
  FileFrameSource source(fileOptions(tmp / "d", false));
  ASSERT_TRUE(source.open().has_value());
  cv::Mat buffer(omniSize(), CV_8UC1);
  std::vector<int> delivered;
  std::vector<std::string> errors;
  for (;;) {
    auto got = source.next(buffer, 10ms);
    if (got) {
      delivered.push_back(got->index);
      continue;
    }
    if (got.error().code() == ErrorCode::kEndOfStream) break;
    ASSERT_EQ(got.error().code(), ErrorCode::kBadFrame) << got.error().c_str();
    errors.emplace_back(got.error().message());
  }
  ASSERT_EQ(errors.size(), 2u);
  EXPECT_THAT(errors[0], HasSubstr("000002.png"));
  EXPECT_THAT(errors[1], HasSubstr("000004.png"));
  EXPECT_THAT(errors[1], HasSubstr("120x100"));
  EXPECT_EQ(delivered.size(), static_cast<std::size_t>(kFrames - 2));
  EXPECT_EQ(std::count(delivered.begin(), delivered.end(), 2), 0);
}

TEST(FileFrameSource, VanishedDirectoryIsADisconnectAndReopenResumesAtTheSameFrame) {
  TempDir tmp("filesrc-gone");
  testing::copyDataset(yawDataset(), tmp / "d");
  FileFrameSource source(fileOptions(tmp / "d", false));
  ASSERT_TRUE(source.open().has_value());
  cv::Mat buffer(omniSize(), CV_8UC1);
  for (int i = 0; i < 5; ++i) ASSERT_TRUE(source.next(buffer, 10ms).has_value());
  fs::rename(tmp / "d", tmp / "away");
  auto gone = source.next(buffer, 10ms);
  ASSERT_FALSE(gone.has_value());
  EXPECT_EQ(gone.error().code(), ErrorCode::kDisconnected);
  EXPECT_THAT(gone.error().message(), HasSubstr((tmp / "d").string())) << gone.error().c_str();
  source.close();
  auto reopen = source.open();
  ASSERT_FALSE(reopen.has_value());
  EXPECT_EQ(reopen.error().code(), ErrorCode::kNotFound);
  fs::rename(tmp / "away", tmp / "d");
  ASSERT_TRUE(source.open().has_value());
  auto next = source.next(buffer, 10ms);
  ASSERT_TRUE(next.has_value());
  EXPECT_EQ(next->index, 5) << "nothing is lost: the frame that failed is read again";
  EXPECT_EQ(next->sequence, 5u);
}

TEST(FileFrameSource, LoopStartsAgainWithTheSequenceCounting) {
  FileFrameSource source(fileOptions(yawDataset(), false, /*loop=*/true));
  ASSERT_TRUE(source.open().has_value());
  cv::Mat buffer(omniSize(), CV_8UC1);
  for (int i = 0; i < kFrames + 3; ++i) {
    auto got = source.next(buffer, 10ms);
    ASSERT_TRUE(got.has_value());
    EXPECT_EQ(got->sequence, static_cast<std::uint64_t>(i));
    EXPECT_EQ(got->index, i % kFrames);
  }
}

TEST(FileFrameSource, RealtimeResynchronisesOnAJumpInsteadOfSleepingThroughIt) {
  // Frames 0-2 at 30 fps, frame 3 a day later; looping, the mean interval the loop would wait
  // is inflated by the jump too. Every frame comes at once, the jumped ones flagged.
  TempDir tmp("file-jump");
  testing::copyDataset(yawDataset(), tmp / "d");
  for (int i = 4; i < kFrames; ++i) fs::remove(tmp / "d/frames" / testing::frameName(i));
  testing::writeText(tmp / "d/timestamps.txt",
                     "000000.png 0\n000001.png 0.0333\n000002.png 0.0667\n000003.png 86400\n");
  FileFrameSource::Options options = fileOptions(tmp / "d", /*realtime=*/true, /*loop=*/true);
  FileFrameSource source(options);
  ASSERT_TRUE(source.open().has_value());
  cv::Mat buffer(omniSize(), CV_8UC1);
  const auto start = SteadyClockNow();
  std::vector<bool> flagged;
  while (flagged.size() < 9 && SteadyClockNow() - start < 10s) {
    auto got = source.next(buffer, 50ms);
    if (!got && got.error().code() == ErrorCode::kTimeout) continue;
    ASSERT_TRUE(got.has_value()) << got.error().c_str();
    EXPECT_EQ(got->index, static_cast<int>(flagged.size() % 4));
    flagged.push_back(got->resynchronised);
  }
  ASSERT_EQ(flagged.size(), 9u) << "a frame was waited for instead of resynchronised";
  EXPECT_LT(SteadyClockNow() - start, 3s);
  // The day-long jump (frames 3 and 7) and the inflated loop interval (frames 4 and 8).
  EXPECT_EQ(flagged, (std::vector<bool>{false, false, false, true, true, false, false, true, true}));
}

TEST(SourceFactory, BuildsTheConfiguredSourceOrSaysWhatIsNotBuiltIn) {
  SourceConfig config;
  config.type = SourceConfig::Type::kFile;
  config.path = yawDataset();
  auto source = daemon::makeFrameSource(config, {omniSize(), yawDataset() / "calibration.yaml", {}});
  ASSERT_NE(source, nullptr);
  EXPECT_THAT(source->describe(), HasSubstr(yawDataset().string()));
  // Camera sources are created, not opened: no device is needed. V4L2 is always built in.
  config.type = SourceConfig::Type::kV4l2;
  auto v4l2 = daemon::makeFrameSource(config, {omniSize(), {}, {}});
  ASSERT_NE(v4l2, nullptr);
  EXPECT_THAT(v4l2->describe(), HasSubstr("v4l2 " + config.device));
  // libcamera is built in when drivers/libcamera found it (OMNIPOSE_HAVE_LIBCAMERA, set for
  // this test as for the source factory: tests/daemon/CMakeLists.txt); else a clear
  // start-up error that names it.
  config.type = SourceConfig::Type::kLibcamera;
#if defined(OMNIPOSE_HAVE_LIBCAMERA)
  auto camera = daemon::makeFrameSource(config, {omniSize(), {}, {}});
  ASSERT_NE(camera, nullptr);
  EXPECT_THAT(camera->describe(), HasSubstr("libcamera camera " + config.camera));
#else
  try {
    daemon::makeFrameSource(config, {omniSize(), {}, {}});
    ADD_FAILURE() << "expected 'not built into this daemon' for libcamera";
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("not built into this daemon"));
    EXPECT_THAT(e.what(), HasSubstr("libcamera"));
  }
#endif
}

// ---------------------------------------------------------------------------------------
// The capture loop: the one owner of reconnection
// ---------------------------------------------------------------------------------------

/// Delivers numbered frames; the delivery `fail_at` fails with kDisconnected (once); then
/// the first `failed_opens` open() calls fail. Records the time of every open() attempt.
class FlakySource final : public FrameSource {
 public:
  FlakySource(cv::Size size, long fail_at, int failed_opens)
      : size_(size), fail_at_(fail_at), failed_opens_(failed_opens) {}
  Expected<void> open() override {
    opens_.push_back(SteadyClock::now());
    if (failed_opens_ > 0) {
      --failed_opens_;
      return fail(ErrorCode::kNoDevice, "flaky: not there");
    }
    return {};
  }
  cv::Size frameSize() const override { return size_; }
  Expected<FrameInfo> next(cv::Mat& out, std::chrono::milliseconds) override {
    std::this_thread::sleep_for(1ms);
    const long n = delivery_++;
    if (n == fail_at_) {
      failed_at_ = SteadyClock::now();
      return fail(ErrorCode::kDisconnected, "flaky: unplugged at %ld", n);
    }
    out.setTo(cv::Scalar(static_cast<double>(n % 200)));
    FrameInfo info;
    info.sequence = static_cast<std::uint64_t>(n);
    info.capture_time_us = daemon::wallClockMicros();
    return info;
  }
  void close() override { ++closes_; }
  std::string describe() const override { return "flaky"; }

  const std::vector<SteadyClock::time_point>& opens() const { return opens_; }
  SteadyClock::time_point failedAt() const { return failed_at_; }
  int closes() const { return closes_; }

 private:
  cv::Size size_;
  long fail_at_;
  int failed_opens_;
  long delivery_ = 0;
  int closes_ = 0;
  std::vector<SteadyClock::time_point> opens_;
  SteadyClock::time_point failed_at_{};
};

TEST(CaptureLoop, AnOutageIsOneSourceFailureRetriedWithBackoffAndStreamingResumes) {
  const cv::Size size(16, 8);
  daemon::StatusBoard board(nullptr);
  FrameMailbox box(size, /*lossless=*/false, 3, &board.frames_skipped_stale);
  FlakySource source(size, /*fail_at=*/5, /*failed_opens=*/4);
  daemon::CaptureLoop::Options options;
  options.poll = 20ms;
  options.reconnect_initial = 10ms;
  options.reconnect_max = 40ms;
  daemon::CaptureLoop loop(source, box, board, options);
  std::thread capture([&] { loop.run(); });

  std::int64_t taken = 0;
  int gaps = 0;
  bool saw_reconnecting = false;
  const auto deadline = SteadyClockNow() + 30s;
  MailboxFrame f;
  while (taken < 20 && SteadyClockNow() < deadline) {
    if (board.sourceState() == daemon::SourceState::kReconnecting) saw_reconnecting = true;
    if (box.take(SteadyClockNow() + 2ms, f) == FrameMailbox::TakeResult::kFrame) {
      ++taken;
      if (f.gap_before) ++gaps;
      box.release();
    }
  }
  box.requestStop();
  capture.join();

  EXPECT_EQ(taken, 20) << "streaming resumed after the outage";
  EXPECT_EQ(board.source_failures.load(), 1) << "one outage, however many attempts";
  EXPECT_TRUE(saw_reconnecting);
  EXPECT_EQ(board.sourceState(), daemon::SourceState::kStopped);
  EXPECT_EQ(gaps, 1) << "the first frame after the re-open follows a gap";
  EXPECT_GE(source.closes(), 2) << "closed at the failure and at the stop";
  // Four refused attempts, then the one that worked, each after its back-off delay.
  const auto& opens = source.opens();
  ASSERT_EQ(opens.size(), 5u);
  const std::chrono::milliseconds delays[] = {10ms, 20ms, 40ms, 40ms, 40ms};
  auto previous = source.failedAt();
  for (std::size_t i = 0; i < opens.size(); ++i) {
    EXPECT_GE(opens[i] - previous, delays[i]) << "attempt " << i;
    previous = opens[i];
  }
  // Every frame counted once.
  EXPECT_EQ(board.frames_received.load(),
            taken + board.frames_skipped_stale.load() + board.frames_bad.load() +
                board.frames_lost_upstream.load());
}

// ---------------------------------------------------------------------------------------
// Whole daemon over memq://
// ---------------------------------------------------------------------------------------

/// Subscribes to the daemon's channels on a shared memq:// LCM and keeps every message.
struct Bus {
  lcm::LCM lcm{"memq://"};
  std::vector<pose_t> poses;
  std::vector<std::int64_t> pose_received_us;
  std::vector<status_t> statuses;
  std::vector<fit_diagnostics_t> diagnostics;
  std::vector<panorama_image_t> pictures;

  Bus() {
    lcm.subscribe("OMNI_POSE", &Bus::onPose, this)->setQueueCapacity(1 << 20);
    lcm.subscribe("OMNI_STATUS", &Bus::onStatus, this)->setQueueCapacity(1 << 20);
    lcm.subscribe("OMNI_FIT", &Bus::onFit, this)->setQueueCapacity(1 << 20);
    lcm.subscribe("OMNI_PANORAMA", &Bus::onPicture, this)->setQueueCapacity(1 << 20);
  }
  void onPicture(const lcm::ReceiveBuffer*, const std::string&, const panorama_image_t* m) {
    pictures.push_back(*m);
  }
  void onPose(const lcm::ReceiveBuffer* rb, const std::string&, const pose_t* p) {
    poses.push_back(*p);
    pose_received_us.push_back(rb->recv_utime);  // memq: the time of publishing
  }
  void onStatus(const lcm::ReceiveBuffer*, const std::string&, const status_t* s) { statuses.push_back(*s); }
  void onFit(const lcm::ReceiveBuffer*, const std::string&, const fit_diagnostics_t* d) { diagnostics.push_back(*d); }
  void drain() {
    while (lcm.handleTimeout(0) > 0) {
    }
  }
  std::unique_ptr<daemon::MessageSink> sink() { return std::make_unique<testing::SharedLcmSink>(lcm); }

  /// Runs `d` to its end (finite source) or until `until` returns true (then stops it).
  void run(Daemon& d, std::chrono::seconds timeout, const std::function<void()>& tick = {}) {
    const auto deadline = SteadyClockNow() + timeout;
    d.start();
    while (!d.waitFinished(10ms)) {
      drain();
      if (tick) tick();
      if (SteadyClockNow() > deadline) {
        ADD_FAILURE() << "daemon did not finish in time";
        d.requestStop();
      }
    }
    d.join();
    drain();
  }
};

DaemonConfig parseConfig(const std::string& yaml, const fs::path& base = "/") {
  return DaemonConfig::parse(yaml, "test.yaml", base);
}

/// Ground-truth relative rotation between dataset frames i and j (T_i^-1 T_j).
Eigen::Matrix3d gtRelative(const std::vector<StampedPose>& gt, int i, int j) {
  return (gt[static_cast<std::size_t>(i)].pose.inverse() * gt[static_cast<std::size_t>(j)].pose).rotation();
}

/// Checks every non-lost pose against the ground truth and its reference frame (frames are
/// matched to the ground truth by their recorded timestamp, so frames inserted into a dataset
/// do not shift the match).
void expectPosesMatchGroundTruth(const std::vector<pose_t>& poses, const fs::path& dataset,
                                 double max_error_rad) {
  const auto gt = readTum(dataset / "groundtruth.tum");
  auto gtIndex = [&](double stamp) {
    for (std::size_t k = 0; k < gt.size(); ++k)
      if (std::abs(gt[k].timestamp - stamp) < 1e-6) return static_cast<int>(k);
    return -1;
  };
  std::map<std::int64_t, int> index_of;  // sequence -> ground-truth index
  for (const auto& p : poses) index_of[p.sequence] = gtIndex(p.source_timestamp);
  for (const auto& p : poses) {
    if (p.status == pose_t::STATUS_LOST) continue;
    ASSERT_TRUE(index_of.contains(p.reference_sequence)) << "reference frame was never published";
    const int i = index_of[p.reference_sequence];
    const int j = index_of[p.sequence];
    ASSERT_GE(i, 0);
    ASSERT_GE(j, 0);
    const double err = testing::rotationError(testing::relativeRotation(p), gtRelative(gt, i, j));
    EXPECT_LT(err, max_error_rad) << "pair " << i << " -> " << j;
  }
}

/// The chained orientation of every pose of segment 0 against the ground truth's attitude
/// relative to the segment's first frame.
void expectChainMatchesGroundTruth(const std::vector<pose_t>& poses, const fs::path& dataset,
                                   double max_error_rad) {
  const auto gt = readTum(dataset / "groundtruth.tum");
  auto gtAt = [&](double stamp) -> const StampedPose* {
    for (const auto& g : gt)
      if (std::abs(g.timestamp - stamp) < 1e-6) return &g;
    return nullptr;
  };
  ASSERT_FALSE(poses.empty());
  const StampedPose* first = gtAt(poses.front().source_timestamp);
  ASSERT_NE(first, nullptr);
  for (const auto& p : poses) {
    if (p.segment != 0) continue;
    const StampedPose* g = gtAt(p.source_timestamp);
    ASSERT_NE(g, nullptr);
    const Eigen::Matrix3d truth = first->pose.linear().transpose() * g->pose.linear();
    const Eigen::Quaterniond q(p.orientation[0], p.orientation[1], p.orientation[2],
                               p.orientation[3]);
    EXPECT_LT(testing::rotationError(q.toRotationMatrix(), truth), max_error_rad)
        << "frame " << p.source_index;
  }
}

TEST(Daemon, PublishesOnePosePerFrameStatusAtItsRateAndAFinalStatus) {
  const auto frames = testing::renderFrames("yaw", 6);
  Bus bus;
  auto config = parseConfig(
      "source: {type: file, path: /nonexistent}\ncalibration: " +
      (yawDataset() / "calibration.yaml").string() + "\nlcm: {status_hz: 20}\n");
  testing::MemorySource::Script script;
  script.total = 40;
  script.period = 20ms;  // 50 Hz, faster than status
  Daemon d(config, stderr, std::make_unique<testing::MemorySource>(frames, script), bus.sink(),
           lossless());
  bus.run(d, 60s);

  const auto stats = d.stats();
  EXPECT_EQ(stats.frames_received, 40);
  EXPECT_EQ(stats.frames_processed, 40);
  EXPECT_EQ(stats.frames_skipped_stale, 0);
  ASSERT_EQ(bus.poses.size(), 40u);
  for (std::size_t k = 0; k < bus.poses.size(); ++k) {
    const pose_t& p = bus.poses[k];
    EXPECT_EQ(p.sequence, static_cast<std::int64_t>(k));
    if (k == 0) {
      EXPECT_EQ(p.status, pose_t::STATUS_LOST) << "first frame: no relative motion yet";
      EXPECT_EQ(p.reference_sequence, -1);
      EXPECT_EQ(p.segment, 0);
    } else {
      EXPECT_EQ(p.status, pose_t::STATUS_OK) << k;
      EXPECT_EQ(p.reference_sequence, p.sequence - 1);
      EXPECT_EQ(p.segment, 0);
      EXPECT_GT(p.utime, bus.poses[k - 1].utime);
    }
    EXPECT_EQ(p.windows_total, 55);
    EXPECT_NEAR(Eigen::Vector4d(p.orientation[0], p.orientation[1], p.orientation[2],
                                p.orientation[3]).norm(), 1.0, 1e-9);
  }
  ASSERT_GE(bus.statuses.size(), 3u) << "status at 20 Hz over a run of 0.8 s or more";
  const status_t& last = bus.statuses.back();
  EXPECT_TRUE(last.final);
  EXPECT_EQ(last.frames_received, 40);
  EXPECT_EQ(last.frames_processed, 40);
  EXPECT_EQ(last.frames_bad, 0);
  EXPECT_EQ(last.poses_lost, 1);
  EXPECT_EQ(last.source_state, status_t::SOURCE_ENDED);
  EXPECT_GT(last.processing_ms_p50, 0.0f);
  EXPECT_GE(last.latency_ms_p99, last.latency_ms_p50);
  // The load over the run: the process used some CPU; the pipeline's thread ran for a part
  // of its time in the pipeline (CPU time is counted in ticks of the kernel's clock: a little
  // above 1 can be rounding); waiting for workers takes no more than the whole frame.
  EXPECT_GT(last.cpu_cores, 0.0f);
  EXPECT_GT(last.processing_cpu_share, 0.0f);
  EXPECT_LE(last.processing_cpu_share, 1.1f);
  EXPECT_GE(last.worker_wait_ms, 0.0f);
  EXPECT_LE(last.worker_wait_ms, last.processing_ms_p99 * 1.5f);
  for (const status_t& s : bus.statuses) {
    EXPECT_GE(s.cpu_cores, 0.0f);
    EXPECT_GE(s.processing_cpu_share, 0.0f);
    EXPECT_GE(s.worker_wait_ms, 0.0f);
    // How often the frames waited for a worker: a share, and none without any time waited.
    EXPECT_GE(s.frames_waited_share, 0.0f);
    EXPECT_LE(s.frames_waited_share, 1.0f);
    if (s.frames_waited_share > 0.0f) {
      EXPECT_GT(s.worker_wait_ms, 0.0f);
    }
    // pipeline.threads 0: every core this process may use, of which 1 or more take part.
    EXPECT_EQ(s.threads, omnipose::runtime::WorkerPool::onlineCores());
    EXPECT_GE(s.threads_active, 1);
    EXPECT_LE(s.threads_active, s.threads);
  }
  EXPECT_EQ(last.source, "memory (6 frames)");
  for (std::size_t k = 0; k + 1 < bus.statuses.size(); ++k) EXPECT_FALSE(bus.statuses[k].final);
  EXPECT_TRUE(bus.diagnostics.empty()) << "diagnostics are off by default";
}

TEST(Daemon, AReportedExposureThatIsNotOneIsReportedAndNoFrameIsLost) {
  // Frame 5 of the recording states an exposure of half a second: every frame still has its
  // pose (the calibration's exposure holds for it), and the fault names the frame.
  TempDir tmp("daemon-exposure");
  testing::copyDataset(yawDataset(), tmp / "d");
  {
    std::ofstream out(tmp / "d" / "timestamps.txt");
    for (int i = 0; i < kFrames; ++i)
      out << testing::frameName(i) << ' ' << i / 30.0 << (i == 5 ? " 0.5" : " 0.004") << '\n';
  }
  Bus bus;
  Daemon d(parseConfig(testing::fileSourceConfig(tmp / "d", "", /*realtime=*/false)), nullptr,
           nullptr, bus.sink());
  bus.run(d, 60s);
  ASSERT_EQ(bus.poses.size(), static_cast<std::size_t>(kFrames));
  const status_t& last = bus.statuses.back();
  EXPECT_EQ(last.frames_bad, 0);
  EXPECT_THAT(last.last_error, HasSubstr("frame 5: its source reported an exposure of 0.5 s"));
}

TEST(Daemon, CorruptFramesMidStreamAreSkippedReportedAndMarkTheGap) {
  TempDir tmp("daemon-corrupt");
  testing::copyDataset(yawDataset(), tmp / "d");
  testing::writeText(tmp / "d/frames/000008.png", "garbage, not an image");
  cv::imwrite((tmp / "d/frames/000015.png").string(), cv::Mat(360, 360, CV_8UC1, cv::Scalar(80)));
  std::FILE* log = std::tmpfile();
  Bus bus;
  Daemon d(parseConfig(testing::fileSourceConfig(tmp / "d", "", /*realtime=*/false)), log,
           nullptr, bus.sink());
  bus.run(d, 60s);

  // Every good frame has its pose; the two bad ones are counted, not published.
  ASSERT_EQ(bus.poses.size(), static_cast<std::size_t>(kFrames - 2));
  const status_t& last = bus.statuses.back();
  EXPECT_TRUE(last.final);
  EXPECT_EQ(last.frames_bad, 2);
  EXPECT_EQ(last.frames_received, kFrames);
  EXPECT_EQ(last.frames_processed, kFrames - 2);
  EXPECT_THAT(last.last_error, HasSubstr("000015.png"));
  EXPECT_THAT(last.last_error, HasSubstr("360x360"));
  EXPECT_GT(last.last_error_utime, 0);
  // The first fault was logged with its file name.
  std::rewind(log);
  std::string logged(1 << 16, '\0');
  logged.resize(std::fread(logged.data(), 1, logged.size(), log));
  std::fclose(log);
  EXPECT_THAT(logged, HasSubstr("000008.png"));

  // The frame after each bad one is found again against the keyframe: the chain goes on in
  // segment 0, its relative pose spans the gap (checked against the ground truth below).
  for (const pose_t& p : bus.poses) {
    const bool after_gap = p.source_index == 9 || p.source_index == 16;
    if (p.source_index == 0) {
      EXPECT_EQ(p.status, pose_t::STATUS_LOST);
      EXPECT_EQ(p.track_state, pose_t::TRACK_START);
      EXPECT_EQ(p.reference_sequence, -1);
      EXPECT_TRUE(std::isinf(p.covariance[0]));
      EXPECT_EQ(p.rotation_vector[2], 0.0);
    } else {
      EXPECT_EQ(p.status, pose_t::STATUS_OK) << p.source_index;
      EXPECT_EQ(p.track_state, after_gap ? pose_t::TRACK_BRIDGED : pose_t::TRACK_TRACKED)
          << p.source_index;
      EXPECT_EQ(p.reference_sequence, p.sequence - (after_gap ? 2 : 1)) << p.source_index;
      EXPECT_GE(p.keyframe_sequence, 0);
      EXPECT_EQ(p.frames_since_keyframe, p.sequence - p.keyframe_sequence);
    }
    EXPECT_EQ(p.segment, 0) << p.source_index;
  }
  EXPECT_EQ(last.segment, 0);
  EXPECT_EQ(last.poses_lost, 1) << "only the first frame has no motion";
  expectPosesMatchGroundTruth(bus.poses, tmp / "d", 0.01);
  expectChainMatchesGroundTruth(bus.poses, tmp / "d", 0.01);
}

TEST(Daemon, PublishesTheSamePosesAsTheReplayThroughBadFramesAndGaps) {
  // One frame-to-pose policy: the daemon (file source, as fast as possible) and
  // omnipose-replay, given the same daemon.yaml (keyframes on), the same frames, two bad
  // ones and a half-second hole in the timestamps, must chain the same poses.
  TempDir tmp("daemon-vs-replay");
  testing::copyDataset(yawDataset(), tmp / "d");
  testing::writeText(tmp / "d/frames/000008.png", "garbage, not an image");
  cv::imwrite((tmp / "d/frames/000015.png").string(), cv::Mat(360, 360, CV_8UC1, cv::Scalar(80)));
  {
    std::ifstream in(tmp / "d/timestamps.txt");
    std::ostringstream out;
    std::string name;
    double t = 0.0;
    int k = 0;
    while (in >> name >> t) out << name << ' ' << std::fixed << (t + (k++ >= 19 ? 0.5 : 0.0)) << '\n';
    testing::writeText(tmp / "d/timestamps.txt", out.str());
  }
  const std::string config_text = testing::fileSourceConfig(tmp / "d", "", /*realtime=*/false) +
                                  "keyframes:\n  slots: 3\n";
  testing::writeText(tmp / "daemon.yaml", config_text);

  Bus bus;
  Daemon d(parseConfig(config_text), stderr, nullptr, bus.sink());
  bus.run(d, 60s);

  replay::ReplayOptions options;
  options.dataset = tmp / "d";
  options.config = tmp / "daemon.yaml";
  options.out_tum = tmp / "replay.tum";
  options.progress = false;
  const replay::ReplaySummary summary = replay::run(options, stderr);
  const std::vector<StampedPose> replayed = readTum(tmp / "replay.tum");

  ASSERT_EQ(bus.poses.size(), static_cast<std::size_t>(kFrames - 2));
  EXPECT_EQ(summary.skipped, 2);
  EXPECT_EQ(bus.statuses.back().frames_bad, summary.skipped);
  int bridged = 0, lost = 0;
  std::size_t next = 0;
  for (const pose_t& p : bus.poses) {
    bridged += p.track_state == pose_t::TRACK_BRIDGED;
    if (p.track_state == pose_t::TRACK_LOST) {
      ++lost;
      continue;  // the replay writes no pose for a lost frame
    }
    ASSERT_LT(next, replayed.size()) << "frame " << p.source_index;
    const StampedPose& r = replayed[next++];
    SCOPED_TRACE("frame " + std::to_string(p.source_index));
    EXPECT_NEAR(r.timestamp, p.source_timestamp, 1e-6);
    const Eigen::Quaterniond q(p.orientation[0], p.orientation[1], p.orientation[2],
                               p.orientation[3]);
    EXPECT_LT(testing::rotationError(q.toRotationMatrix(), r.pose.linear()), 1e-7);
    EXPECT_LT((Eigen::Vector3d(p.position[0], p.position[1], p.position[2]) - r.pose.translation())
                  .norm(),
              1e-7);
  }
  EXPECT_EQ(next, replayed.size());
  EXPECT_EQ(bridged, summary.bridged);
  EXPECT_EQ(lost, summary.lost);
  EXPECT_EQ(bridged, 3) << "after each bad frame and after the hole";
  EXPECT_EQ(lost, 0);
}

TEST(Daemon, VanishingDirectoryIsReportedRetriedWithBackoffAndMarksTheGap) {
  TempDir tmp("daemon-vanish");
  testing::copyDataset(yawDataset(), tmp / "d");
  Bus bus;
  auto config = parseConfig(testing::fileSourceConfig(tmp / "d", "", false) + "  status_hz: 20\n");
  Daemon d(config, stderr, nullptr, bus.sink());
  bool moved = false, noticed = false, restored = false;
  SteadyClock::time_point noticed_at;
  bus.run(d, 60s, [&] {
    if (!moved && bus.poses.size() >= 6) {
      fs::rename(tmp / "d", tmp / "away");
      moved = true;
    } else if (moved && !noticed && d.stats().source_failures >= 1) {
      // The outage lasts 700 ms from when the daemon noticed it, however slow the machine
      // (or a sanitizer) makes reaching the next frame.
      noticed = true;
      noticed_at = SteadyClockNow();
    } else if (noticed && !restored && SteadyClockNow() - noticed_at > 700ms) {
      fs::rename(tmp / "away", tmp / "d");
      restored = true;
    }
  });
  ASSERT_TRUE(restored);
  const auto stats = d.stats();
  EXPECT_GE(stats.source_failures, 1);
  EXPECT_EQ(stats.frames_received, kFrames) << "the failed frame is read again after the re-open";
  // Status showed the reconnecting source with the directory named.
  bool saw_reconnecting = false;
  for (const auto& s : bus.statuses) {
    if (s.source_state == status_t::SOURCE_RECONNECTING) {
      saw_reconnecting = true;
      EXPECT_THAT(s.last_error, HasSubstr((tmp / "d").string()));
    }
  }
  EXPECT_TRUE(saw_reconnecting);
  EXPECT_EQ(bus.statuses.back().source_state, status_t::SOURCE_ENDED);
  // The outage is bridged: one pose spans it, the chain stays in segment 0.
  ASSERT_EQ(bus.poses.size(), static_cast<std::size_t>(kFrames));
  int bridged = 0;
  for (std::size_t k = 1; k < bus.poses.size(); ++k) {
    const pose_t& p = bus.poses[k];
    EXPECT_NE(p.status, pose_t::STATUS_LOST) << k;
    EXPECT_EQ(p.segment, 0);
    EXPECT_EQ(p.reference_sequence, bus.poses[k - 1].sequence);
    if (p.track_state == pose_t::TRACK_BRIDGED) ++bridged;
  }
  EXPECT_EQ(bridged, 1);
  expectChainMatchesGroundTruth(bus.poses, tmp / "d", 0.01);
  expectPosesMatchGroundTruth(bus.poses, tmp / "d", 0.01);
}

TEST(Daemon, StaleFramesAreSkippedAndLatencyStaysBounded) {
  // A 200 fps recording replayed in real time: far faster than the pipeline.
  TempDir tmp("daemon-stale");
  testing::copyDataset(yawDataset(), tmp / "d");
  testing::writeTimestamps(tmp / "d", kFrames, [](int i) { return 0.005 * i; });
  Bus bus;
  auto config = parseConfig(testing::fileSourceConfig(tmp / "d", "", /*realtime=*/true, /*loop=*/true) +
                            "  status_hz: 10\n");
  Daemon d(config, stderr, nullptr, bus.sink());
  bus.run(d, 60s, [&] {
    if (bus.poses.size() >= 25) d.requestStop();
  });
  const auto stats = d.stats();
  ASSERT_GE(bus.poses.size(), 25u);
  EXPECT_GT(stats.frames_skipped_stale, 0);
  const status_t& last = bus.statuses.back();
  EXPECT_TRUE(last.final);
  EXPECT_EQ(last.source_state, status_t::SOURCE_STOPPED);
  EXPECT_EQ(last.frames_skipped_stale, stats.frames_skipped_stale);
  // Every received frame is accounted for once, also the one still in the mailbox at the
  // stop and the ones the source passed over while it was late.
  EXPECT_EQ(last.frames_received, last.frames_processed + last.frames_skipped_stale +
                                      last.frames_bad + last.frames_lost_upstream);
  std::int64_t skipped_in_poses = 0;
  for (const auto& p : bus.poses) skipped_in_poses += p.frames_skipped;
  EXPECT_LE(skipped_in_poses, stats.frames_skipped_stale);

  // Latency (capture -> publish) stays within a couple of processing times instead of
  // growing with a backlog: the last poses are as fresh as the first ones.
  double max_processing_ms = 0;
  for (const auto& p : bus.poses) max_processing_ms = std::max<double>(max_processing_ms, p.processing_time_s * 1e3);
  std::vector<double> latency_ms;
  for (std::size_t k = 0; k < bus.poses.size(); ++k)
    latency_ms.push_back((bus.pose_received_us[k] - bus.poses[k].utime) * 1e-3);
  const double bound = 3.0 * max_processing_ms + 100.0;
  for (std::size_t k = 0; k < latency_ms.size(); ++k) {
    EXPECT_GE(latency_ms[k], 0.0);
    EXPECT_LT(latency_ms[k], bound) << "pose " << k << " (max processing " << max_processing_ms << " ms)";
  }
  EXPECT_LT(last.latency_ms_p99, bound);
  // Capture stamps are the recorded schedule: 5 ms apart per dataset frame.
  for (std::size_t k = 1; k < bus.poses.size(); ++k) {
    const pose_t& a = bus.poses[k - 1];
    const pose_t& b = bus.poses[k];
    if (b.sequence <= a.sequence) continue;
    EXPECT_NEAR(static_cast<double>(b.utime - a.utime), 5000.0 * static_cast<double>(b.sequence - a.sequence), 2.0);
    if (b.status != pose_t::STATUS_LOST) {
      // Skipped as stale by the daemon, or never read by the source (running late).
      EXPECT_LE(b.frames_skipped, b.sequence - a.sequence - 1);
      EXPECT_EQ(b.reference_sequence, a.sequence);
    }
  }
}

/// RMS over the tracked poses of the error of their relative rotation against the ground
/// truth of `dataset`, radians.
double relativeRotationRms(const std::vector<pose_t>& poses, const fs::path& dataset) {
  const auto gt = readTum(dataset / "groundtruth.tum");
  std::map<std::int64_t, double> stamp;  // sequence -> recorded timestamp
  for (const pose_t& p : poses) stamp[p.sequence] = p.source_timestamp;
  const auto at = [&](double t) {
    for (std::size_t k = 0; k < gt.size(); ++k)
      if (std::abs(gt[k].timestamp - t) < 1e-6) return static_cast<int>(k);
    return -1;
  };
  double sum = 0.0;
  int n = 0;
  for (const pose_t& p : poses) {
    if (p.status == pose_t::STATUS_LOST) continue;
    const int i = at(stamp.at(p.reference_sequence)), j = at(p.source_timestamp);
    if (i < 0 || j < 0) continue;
    const double e = testing::rotationError(testing::relativeRotation(p), gtRelative(gt, i, j));
    sum += e * e;
    ++n;
  }
  return n > 0 ? std::sqrt(sum / n) : std::numeric_limits<double>::infinity();
}

TEST(Daemon, TheRobotsGyroOverLcmTakesTheRollingShutterOut) {
  // The gyro's clock runs 0.5 s ahead of the recording's, so that every utime is positive.
  const fs::path dataset = testing::cachedDataset("gyro", [](const fs::path& dir) {
    testing::writeGyroDataset(dir, testing::indoorPhoto(), 13, 0.5);
  });
  TempDir tmp("gyro");
  std::vector<testing::LcmEvent> events;
  for (const GyroSample& s : readGyroCsv(dataset / "imu.csv").samples)
    events.push_back(testing::imuEvent(s));
  testing::writeLcmLog(tmp / "imu.lcm", events);
  const auto run = [&](const std::string& imu, status_t& last, std::FILE* log = stderr) {
    Bus bus;
    const auto config = parseConfig(testing::fileSourceConfig(dataset, "memq://", true) + imu);
    Daemon d(config, log, nullptr, bus.sink(), lossless());
    EXPECT_EQ(d.imuDescription().empty(), imu.empty());
    bus.run(d, 120s);
    EXPECT_FALSE(bus.statuses.empty());
    if (!bus.statuses.empty()) last = bus.statuses.back();
    return relativeRotationRms(bus.poses, dataset);
  };
  status_t with{}, without{};
  const double with_gyro = run(
      "imu: {source: lcm, url: \"file://" + (tmp / "imu.lcm").string() + "?speed=0\"}\n", with);
  const double images_alone = run("", without);
  ::testing::Test::RecordProperty("rotation_rms_with_gyro", std::to_string(with_gyro));
  ::testing::Test::RecordProperty("rotation_rms_images_alone", std::to_string(images_alone));

  EXPECT_EQ(with.imu_samples, static_cast<std::int64_t>(events.size()));
  EXPECT_EQ(with.imu_samples_refused + with.imu_messages_bad + with.imu_samples_dropped, 0);
  // The log is read in milliseconds and the frames come at 30 fps: the first frame may still
  // find the gyro's queue empty. A slow build (ASan) skips frames of the realtime source as
  // stale (4 of 13 once, more on a loaded machine): every frame received is accounted for,
  // and enough are processed to compare.
  EXPECT_EQ(with.frames_processed + with.frames_skipped_stale + with.frames_bad +
                with.frames_lost_upstream,
            with.frames_received);
  EXPECT_GE(with.frames_processed, 5);
  EXPECT_GE(with.frames_with_gyro, with.frames_processed - 1);
  EXPECT_EQ(with.frames_with_gyro + with.frames_without_gyro, with.frames_processed);
  EXPECT_EQ(without.imu_samples, 0);
  EXPECT_EQ(without.frames_with_gyro, 0);
  // The calibration's imu section, no stream.
  EXPECT_EQ(without.frames_without_gyro, without.frames_processed);
  EXPECT_LT(with_gyro, 0.5 * images_alone);
  EXPECT_THAT(without.last_error, ::testing::Not(::testing::HasSubstr("gyro")))
      << "no stream configured: nothing to report";

  // A stream that stops 0.1 s into the recording (its first 40 samples, from 0.1 s before the
  // first frame): the frames after are registered from the images alone, counted, reported.
  events.resize(40);
  testing::writeLcmLog(tmp / "short.lcm", events);
  status_t stopped{};
  std::FILE* log = std::tmpfile();
  run("imu: {source: lcm, url: \"file://" + (tmp / "short.lcm").string() + "?speed=0\"}\n",
      stopped, log);
  EXPECT_GE(stopped.frames_without_gyro, stopped.frames_processed - 3);
  EXPECT_EQ(stopped.frames_with_gyro + stopped.frames_without_gyro, stopped.frames_processed);
  // The faults' lines (the stream's end and the frames after it, in the order the two
  // threads got to them).
  std::rewind(log);
  std::string text(1 << 16, '\0');
  text.resize(std::fread(text.data(), 1, text.size(), log));
  std::fclose(log);
  EXPECT_THAT(text, ::testing::HasSubstr("the gyro's samples do not cover its readout"));
  EXPECT_THAT(text, ::testing::HasSubstr("imu: the stream on channel OMNI_IMU"));
}

TEST(Daemon, AGyroWithoutItsCalibrationIsAStartUpError) {
  auto config = parseConfig(testing::fileSourceConfig(yawDataset(), "memq://", false) +
                            "imu: {source: lcm, url: \"memq://\"}\n");
  Bus bus;
  try {
    Daemon d(config, stderr, nullptr, bus.sink());
    FAIL() << "no error";
  } catch (const ConfigError& e) {
    EXPECT_THAT(e.what(), ::testing::HasSubstr("imu.source: lcm needs the calibration's imu section"));
  }
}

TEST(Daemon, FitDiagnosticsArePublishedWhenEnabledAndMatchTheModel) {
  Bus bus;
  const auto frames = testing::renderFrames("yaw", 4);
  // The memory source stamps a frame with the wall clock when the daemon takes it: under a
  // sanitizer on a busy machine consecutive frames can be further apart than gap_after_s, and
  // a frame after a gap is registered against the keyframe, not the previous frame. This test
  // is about the pairs' windows, so only reported gaps count.
  auto config = parseConfig("source: {type: file, path: /x}\ncalibration: " +
                            (yawDataset() / "calibration.yaml").string() +
                            "\nlcm: {fit_channel: OMNI_FIT}\nkeyframes: {gap_after_s: 0}\n");
  testing::MemorySource::Script script;
  script.total = 6;
  Daemon d(config, stderr, std::make_unique<testing::MemorySource>(frames, script), bus.sink(),
           lossless());
  bus.run(d, 60s);
  ASSERT_EQ(bus.poses.size(), 6u);
  ASSERT_EQ(bus.diagnostics.size(), 5u) << "one per frame pair";
  for (std::size_t i = 0; i < bus.diagnostics.size(); ++i) {
    const auto& diag = bus.diagnostics[i];
    const pose_t& pose = bus.poses[i + 1];
    ASSERT_EQ(diag.sequence, pose.sequence);
    // The windows of the pass that made the estimate: the refinement pass, on the panorama
    // de-rotated by the first estimate, so what is left of the 1..6 degree yaw is a
    // fraction of a pixel, and the model is that pass's fit.
    EXPECT_TRUE(diag.refined);
    EXPECT_EQ(diag.reference_sequence, pose.reference_sequence)
        << "the windows are the pair's registration, whatever keyframe the pose is anchored to";
    for (int a = 0; a < 3; ++a) EXPECT_EQ(diag.omega[a], pose.rotation_vector[a]);
    ASSERT_EQ(diag.num_windows, 55);
    ASSERT_EQ(diag.du.size(), 55u);
    int valid = 0;
    ASSERT_EQ(diag.weight.size(), 55u);
    ASSERT_EQ(diag.moving_fraction.size(), 55u);
    float heaviest = 0.0f;
    for (int k = 0; k < diag.num_windows; ++k) {
      // How much each window weighed (1 = the heaviest, 0 = left out), and what the
      // moving-content check judged of it (nothing moves in this scene).
      EXPECT_GE(diag.weight[k], 0.0f);
      EXPECT_LE(diag.weight[k], 1.0f);
      heaviest = std::max(heaviest, diag.weight[k]);
      EXPECT_GE(diag.moving_fraction[k], 0.0f);
      EXPECT_LT(diag.moving_fraction[k], 0.06f) << "window " << k;
      if (!diag.valid[k]) {
        EXPECT_EQ(diag.weight[k], 0.0f) << "an invalid window weighs nothing";
        continue;
      }
      ++valid;
      EXPECT_LT(std::abs(diag.du[k]), 1.0) << "window " << k << ": not the refinement pass";
      EXPECT_NEAR(diag.du[k], diag.model_du[k], 0.3) << "window " << k;
      EXPECT_NEAR(diag.dv[k], diag.model_dv[k], 0.3) << "window " << k;
    }
    EXPECT_GT(valid, 40);
    EXPECT_EQ(heaviest, 1.0f);
  }
}

/// The picture PanoramaPictures should make of `frame`: its panorama shrunk to `size`.
cv::Mat expectedPicture(const Calibration& calibration, const cv::Mat& frame, cv::Size size) {
  Unwrapper unwrapper(calibration, {});
  cv::Mat panorama = unwrapper.makePanorama(), small, grey;
  EXPECT_TRUE(unwrapper.unwrap(frame, panorama).has_value());
  cv::resize(panorama, small, size, 0, 0, cv::INTER_AREA);
  small.convertTo(grey, CV_8U);
  return grey;
}

/// Mean absolute grey-level difference of a JPEG picture from `expected`.
double pictureError(const std::vector<std::uint8_t>& jpeg, const cv::Mat& expected) {
  const cv::Mat decoded = cv::imdecode(jpeg, cv::IMREAD_GRAYSCALE);
  EXPECT_EQ(decoded.size(), expected.size());
  if (decoded.size() != expected.size()) return 1e9;
  return cv::norm(decoded, expected, cv::NORM_L1) / static_cast<double>(expected.total());
}

TEST(PanoramaPictures, APictureIsTheFramesPanoramaShrunkAtMostAtItsRate) {
  const Calibration calibration = Calibration::load(yawDataset() / "calibration.yaml");
  const auto frames = testing::renderFrames("yaw", 3);
  daemon::PanoramaPictures pictures(calibration, InputKind::kOmni, /*hz=*/4.0, /*width=*/320);
  const cv::Size size = daemon::PanoramaPictures::pictureSize(
      calibration.panorama.size(), 320);
  EXPECT_EQ(size.width, 320);
  const auto waitReady = [&] {
    for (int i = 0; i < 500 && pictures.ready().empty(); ++i) std::this_thread::sleep_for(10ms);
    return pictures.ready();
  };
  const std::int64_t t0 = 1'700'000'000'000'000;
  ASSERT_TRUE(pictures.offer(frames[0], t0, 7));
  EXPECT_FALSE(pictures.offer(frames[1], t0 + 300'000, 8)) << "one picture at a time";
  const auto first = waitReady();
  ASSERT_FALSE(first.empty());
  panorama_image_t m;
  ASSERT_EQ(m.decode(first.data(), 0, static_cast<int>(first.size())),
            static_cast<int>(first.size()));
  EXPECT_EQ(m.utime, t0);
  EXPECT_EQ(m.sequence, 7);
  EXPECT_EQ(m.format, "jpeg");
  EXPECT_EQ(m.width, size.width);
  EXPECT_EQ(m.height, size.height);
  EXPECT_LT(pictureError(m.data, expectedPicture(calibration, frames[0], size)), 3.0);
  EXPECT_FALSE(pictures.offer(frames[1], t0 + 300'000, 8)) << "not published yet";
  pictures.done();
  EXPECT_TRUE(pictures.ready().empty());
  EXPECT_FALSE(pictures.offer(frames[1], t0 + 200'000, 8)) << "within 1/hz of the last";
  EXPECT_TRUE(pictures.offer(frames[1], t0 + 250'000, 9));
  ASSERT_FALSE(waitReady().empty());
  pictures.done();
  EXPECT_TRUE(pictures.offer(frames[2], t0 - 1'000'000, 10)) << "the clock went back";
  ASSERT_FALSE(waitReady().empty());
  EXPECT_EQ(pictures.made(), 3);
  EXPECT_EQ(pictures.failed(), 0);
  EXPECT_FALSE(pictures.offer(cv::Mat(5, 5, CV_8UC1), t0 + 10'000'000, 11)) << "wrong size";
}

TEST(Daemon, PanoramaPicturesArePublishedWhenAskedAtTheirRate) {
  Bus bus;
  const auto frames = testing::renderFrames("yaw", 4);
  const double hz = 30.0;
  auto config = parseConfig("source: {type: file, path: /x}\ncalibration: " +
                            (yawDataset() / "calibration.yaml").string() +
                            "\nlcm: {panorama_channel: OMNI_PANORAMA, panorama_hz: 30, "
                            "panorama_width: 256}\n");
  testing::MemorySource::Script script;
  script.total = 16;
  script.period = 20ms;
  Daemon d(config, stderr, std::make_unique<testing::MemorySource>(frames, script), bus.sink(),
           lossless());
  bus.run(d, 60s);
  ASSERT_EQ(bus.poses.size(), 16u);
  // At most 30 per second of capture time (the capture times spread further when the
  // processing is slower than the source, as under a sanitizer: the mailbox is lossless);
  // the last one taken may be unpublished when the source ends.
  ASSERT_GE(bus.pictures.size(), 2u);
  const double span_s = static_cast<double>(bus.poses.back().utime - bus.poses.front().utime) * 1e-6;
  EXPECT_LE(static_cast<double>(bus.pictures.size()), span_s * hz + 1.0) << span_s << " s";
  const Calibration calibration = Calibration::load(yawDataset() / "calibration.yaml");
  const cv::Size size = daemon::PanoramaPictures::pictureSize(
      calibration.panorama.size(), 256);
  for (std::size_t i = 0; i < bus.pictures.size(); ++i) {
    const panorama_image_t& m = bus.pictures[i];
    const auto pose = std::find_if(bus.poses.begin(), bus.poses.end(),
                                   [&](const pose_t& p) { return p.sequence == m.sequence; });
    ASSERT_NE(pose, bus.poses.end()) << "picture of a frame without a pose";
    EXPECT_EQ(m.utime, pose->utime);
    if (i > 0) {
      EXPECT_GE(m.utime - bus.pictures[i - 1].utime, std::llround(1e6 / hz));
    }
    // MemorySource's ping-pong order: 0 1 2 3 2 1 0 1 ...
    const std::int64_t cycle = 2 * static_cast<std::int64_t>(frames.size()) - 2;
    std::int64_t k = m.sequence % cycle;
    if (k >= static_cast<std::int64_t>(frames.size())) k = cycle - k;
    const cv::Mat& frame = frames[static_cast<std::size_t>(k)];
    EXPECT_LT(pictureError(m.data, expectedPicture(calibration, frame, size)), 3.0)
        << "picture " << i;
  }
}

TEST(Daemon, StartupFailuresNameTheCulprit) {
  const std::string calibration = (yawDataset() / "calibration.yaml").string();
  auto expectStartupError = [](const DaemonConfig& c, const std::string& needle) {
    try {
      Daemon d(c, nullptr);
      ADD_FAILURE() << "expected a start-up error mentioning " << needle;
    } catch (const std::runtime_error& e) {
      EXPECT_THAT(e.what(), HasSubstr(needle));
    }
  };
  expectStartupError(parseConfig("source: {type: file, path: /no/such/dataset}\ncalibration: " +
                                 calibration + "\nlcm: {url: 'memq://'}\n"),
                     "/no/such/dataset");
  expectStartupError(parseConfig("source: {type: v4l2, device: /dev/omnipose-no-such-video}\n"
                                 "calibration: " + calibration + "\nlcm: {url: 'memq://'}\n"),
                     "/dev/omnipose-no-such-video");
  expectStartupError(parseConfig("source: {type: file, path: " + yawDataset().string() +
                                 "}\ncalibration: /no/such/calibration.yaml\nlcm: {url: 'memq://'}\n"),
                     "/no/such/calibration.yaml");
  expectStartupError(parseConfig("source: {type: file, path: " + yawDataset().string() +
                                 "}\ncalibration: " + calibration + "\nlcm: {url: 'nonsense://x'}\n"),
                     "nonsense://x");
  // A panorama-input configuration on an omni dataset: the frame size does not match.
  expectStartupError(parseConfig("source: {type: file, path: " + yawDataset().string() +
                                 "}\ncalibration: " + calibration +
                                 "\ninput: panorama\nlcm: {url: 'memq://'}\n"),
                     "expected 1100x110");
}

/// A source whose capture clock steps back by one second at delivery `step_at` (a camera
/// clock step): the frames themselves are the ping-pong sequence of MemorySource.
class ClockStepSource final : public FrameSource {
 public:
  ClockStepSource(std::vector<cv::Mat> frames, long total, long step_at)
      : inner_(std::move(frames), {.period = {}, .total = total, .bad = {}, .disconnect = {}}),
        step_at_(step_at) {}
  Expected<void> open() override { return inner_.open(); }
  cv::Size frameSize() const override { return inner_.frameSize(); }
  Expected<FrameInfo> next(cv::Mat& out, std::chrono::milliseconds timeout) override {
    Expected<FrameInfo> got = inner_.next(out, timeout);
    if (got && static_cast<long>(got->sequence) >= step_at_) got->capture_time_us -= 1'000'000;
    return got;
  }
  void close() override { inner_.close(); }
  std::string describe() const override { return "clock-step source"; }

 private:
  testing::MemorySource inner_;
  long step_at_;
};

TEST(DaemonFaults, CaptureClockGoingBackwardsIsAGapBridgedAndReported) {
  const auto frames = testing::renderFrames("yaw", 6);
  Bus bus;
  // Only the step is a gap: frames stamped with the wall clock when the daemon takes them can
  // be further apart than gap_after_s under a sanitizer on a busy machine.
  const auto config = parseConfig("source: {type: file, path: /nonexistent}\ncalibration: " +
                                  (yawDataset() / "calibration.yaml").string() +
                                  "\nkeyframes: {gap_after_s: 0}\n");
  Daemon d(config, nullptr, std::make_unique<ClockStepSource>(frames, 12, 5), bus.sink(),
           lossless());
  bus.run(d, 60s);
  ASSERT_EQ(bus.poses.size(), 12u);
  for (const pose_t& p : bus.poses) {
    SCOPED_TRACE(p.sequence);
    if (p.sequence == 0) {
      EXPECT_EQ(p.status, pose_t::STATUS_LOST);
      EXPECT_EQ(p.reference_sequence, -1);
    } else {
      EXPECT_NE(p.status, pose_t::STATUS_LOST);
      EXPECT_EQ(p.reference_sequence, p.sequence - 1);
      EXPECT_EQ(p.track_state, p.sequence == 5 ? pose_t::TRACK_BRIDGED : pose_t::TRACK_TRACKED);
    }
    EXPECT_EQ(p.segment, 0);
  }
  ASSERT_FALSE(bus.statuses.empty());
  const status_t& last = bus.statuses.back();
  EXPECT_EQ(last.frames_processed, 12);
  EXPECT_EQ(last.poses_lost, 1);
  EXPECT_THAT(last.last_error, HasSubstr("time went backwards"));
  EXPECT_THAT(last.last_error, HasSubstr("clock-step source"));
}

TEST(DaemonFaults, AnLcmLogThatIsNotARegularFileIsRefusedAtStartUp) {
  // /dev/full took every message and failed it: the daemon ran for nothing. A log that is a
  // device, a FIFO or a directory is refused by name before anything starts (a full disk
  // mid-run: OmniposedFaults.LogDiskFullMidRun...).
  const auto frames = testing::renderFrames("yaw", 2);
  TempDir tmp("daemon-special-log");
  ASSERT_EQ(::mkfifo((tmp / "fifo").c_str(), 0600), 0);
  fs::create_directory(tmp / "dir");
  for (const std::string& target : std::vector<std::string>{"/dev/full", "/dev/null", (tmp / "fifo").string(),
                                                              (tmp / "dir").string()}) {
    SCOPED_TRACE(target);
    if (!fs::exists(target)) continue;
    const auto config = parseConfig("source: {type: file, path: /nonexistent}\ncalibration: " +
                                    (yawDataset() / "calibration.yaml").string() +
                                    "\nlcm: {url: 'file://" + target + "?mode=w'}\n");
    testing::MemorySource::Script script;
    script.total = 2;
    try {
      Daemon d(config, stderr, std::make_unique<testing::MemorySource>(frames, script), nullptr,
               lossless());
      ADD_FAILURE() << "started with the log " << target;
    } catch (const std::runtime_error& e) {
      const std::string what = e.what();
      EXPECT_THAT(what, HasSubstr(target + ": not a regular file"));
      EXPECT_THAT(what, HasSubstr("lcm.url"));
    }
  }
}

// ---------------------------------------------------------------------------------------
// Hostile frames and timestamps: nothing stops the daemon, every frame is counted once
// ---------------------------------------------------------------------------------------

void expectEveryFrameCountedOnce(const status_t& s, std::int64_t frames) {
  EXPECT_EQ(s.frames_received, frames);
  EXPECT_EQ(s.frames_received,
            s.frames_processed + s.frames_skipped_stale + s.frames_bad + s.frames_lost_upstream)
      << "received " << s.frames_received << ", processed " << s.frames_processed << ", skipped "
      << s.frames_skipped_stale << ", bad " << s.frames_bad << ", lost " << s.frames_lost_upstream;
}

TEST(DaemonFaults, BombsTruncatedAndGarbageFramesAreSkippedCountedAndNamed) {
  TempDir tmp("daemon-hostile");
  testing::copyDataset(yawDataset(), tmp / "d");
  const cv::Mat good = cv::imread((yawDataset() / "frames/000000.png").string(), cv::IMREAD_UNCHANGED);
  const auto files = testing::badImageFiles(good);
  std::vector<testing::BadImageFile> rejected;
  for (const auto& f : files)
    if (f.must_reject) rejected.push_back(f);
  testing::insertFrames(tmp / "d", 10, rejected);
  std::FILE* log = std::tmpfile();
  Bus bus;
  Daemon d(parseConfig(testing::fileSourceConfig(tmp / "d", "", /*realtime=*/false)), log,
           nullptr, bus.sink());
  bus.run(d, 120s);

  ASSERT_EQ(bus.poses.size(), static_cast<std::size_t>(kFrames)) << "every good frame has its pose";
  ASSERT_FALSE(bus.statuses.empty());
  const status_t& last = bus.statuses.back();
  EXPECT_TRUE(last.final);
  EXPECT_EQ(last.source_state, status_t::SOURCE_ENDED);
  EXPECT_EQ(last.frames_bad, static_cast<std::int64_t>(rejected.size()));
  expectEveryFrameCountedOnce(last, kFrames + static_cast<std::int64_t>(rejected.size()));
  std::string last_name;  // the daemon reads frames in name order
  for (const auto& f : rejected) last_name = std::max(last_name, f.name);
  EXPECT_THAT(last.last_error, HasSubstr("000010_" + last_name));
  std::rewind(log);
  std::string logged(1 << 16, '\0');
  logged.resize(std::fread(logged.data(), 1, logged.size(), log));
  std::fclose(log);
  EXPECT_THAT(logged, HasSubstr("000010_bomb_60000.jpg: 60000x60000, expected 720x720"));
  expectPosesMatchGroundTruth(bus.poses, tmp / "d", 0.01);
}

TEST(DaemonFaults, AFrameThatDecodesButDoesNotFitIsCountedAndTheChainIsUnharmed) {
  // Frame 15 flipped upside down: a glitching camera. Before, its pair and the next came
  // out "degraded" and every later pose was chained 8-19 degrees off.
  TempDir tmp("daemon-glitch");
  testing::copyDataset(yawDataset(), tmp / "d");
  const fs::path glitch = tmp / "d/frames/000015.png";
  cv::Mat flipped;
  cv::flip(cv::imread(glitch.string(), cv::IMREAD_UNCHANGED), flipped, 0);
  ASSERT_TRUE(cv::imwrite(glitch.string(), flipped));
  Bus bus;
  Daemon d(parseConfig(testing::fileSourceConfig(tmp / "d", "", /*realtime=*/false)), nullptr,
           nullptr, bus.sink());
  bus.run(d, 120s);
  ASSERT_FALSE(bus.statuses.empty());
  const status_t& last = bus.statuses.back();
  EXPECT_EQ(last.frames_bad, 1);
  EXPECT_EQ(last.frames_implausible, 1);
  expectEveryFrameCountedOnce(last, kFrames);
  EXPECT_THAT(last.last_error, HasSubstr("implausible frame"));
  ASSERT_EQ(bus.poses.size(), static_cast<std::size_t>(kFrames - 1)) << "no pose for the glitch";
  for (const pose_t& p : bus.poses) {
    EXPECT_NE(p.source_index, 15);
    EXPECT_EQ(p.segment, 0);
    if (p.source_index == 16) {
      EXPECT_EQ(p.reference_sequence, 14) << "against the last believed frame";
    }
    if (p.source_index > 0) {
      EXPECT_EQ(p.status, pose_t::STATUS_OK) << "frame " << p.source_index;
    }
  }
  expectChainMatchesGroundTruth(bus.poses, tmp / "d", 0.05 * std::numbers::pi / 180.0);
}

/// Runs the yaw dataset in realtime with `stamp(i)` as frame i's timestamp; returns the final
/// status and the time the run took.
std::pair<status_t, double> runWithTimestamps(const std::function<double(int)>& stamp,
                                              const std::string& tag) {
  TempDir tmp(tag);
  testing::copyDataset(yawDataset(), tmp / "d");
  testing::writeTimestamps(tmp / "d", kFrames, stamp);
  Bus bus;
  Daemon d(parseConfig(testing::fileSourceConfig(tmp / "d", "", /*realtime=*/true)), nullptr,
           nullptr, bus.sink());
  const auto start = SteadyClockNow();
  bus.run(d, 60s);
  const double seconds = std::chrono::duration<double>(SteadyClockNow() - start).count();
  if (bus.statuses.empty()) return {status_t{}, seconds};
  return {bus.statuses.back(), seconds};
}

TEST(DaemonFaults, EveryFrameIsCountedOnceUnderEqualBackwardAndJumpingTimestamps) {
  {
    SCOPED_TRACE("all timestamps equal: the frames due at once are passed over, as a camera would");
    const auto [s, seconds] = runWithTimestamps([](int) { return 5.0; }, "daemon-equal");
    EXPECT_TRUE(s.final);
    expectEveryFrameCountedOnce(s, kFrames);
    EXPECT_GE(s.frames_processed, 1);
  }
  {
    SCOPED_TRACE("time going backwards every eighth frame");
    const auto [s, seconds] =
        runWithTimestamps([](int i) { return 0.02 * i - (i % 8 == 7 ? 0.1 : 0.0); }, "daemon-back");
    EXPECT_TRUE(s.final);
    expectEveryFrameCountedOnce(s, kFrames);
    EXPECT_THAT(s.last_error, HasSubstr("time went backwards"));
  }
  {
    SCOPED_TRACE("a forward jump of 1e9 s: reported and resynchronised, not waited out");
    // Frames 0.1 s apart: a reader late by a whole interval (a loaded machine) passes frames
    // over and counts them lost upstream, which is not what this checks.
    const auto [s, seconds] =
        runWithTimestamps([](int i) { return 0.1 * i + (i >= 12 ? 1e9 : 0.0); }, "daemon-jump");
    EXPECT_TRUE(s.final);
    expectEveryFrameCountedOnce(s, kFrames);
    EXPECT_EQ(s.frames_lost_upstream, 0);
    EXPECT_THAT(s.last_error, HasSubstr("frame 12"));
    EXPECT_THAT(s.last_error, HasSubstr("resynchronised"));
    EXPECT_LT(seconds, 20.0);
  }
}

// ---------------------------------------------------------------------------------------
// Publish failures reach the published status
// ---------------------------------------------------------------------------------------

/// Refuses every message on one channel; passes the others to the test's memq:// LCM.
class FailingChannelSink final : public daemon::MessageSink {
 public:
  FailingChannelSink(lcm::LCM& lcm, std::string failing) : lcm_(lcm), failing_(std::move(failing)) {}
  bool publish(const std::string& channel, const std::uint8_t* data, std::size_t size) override {
    if (channel == failing_) return false;
    return lcm_.publish(channel, data, static_cast<unsigned int>(size)) == 0;
  }
  std::string describe() const override { return "memq, refusing " + failing_ + " (test)"; }
  const char* lastError() const override { return "test sink refuses the channel"; }

 private:
  lcm::LCM& lcm_;
  std::string failing_;
};

/// The yaw dataset's frames from `from` on, in `dir`.
void datasetFrom(const fs::path& dir, int from) {
  testing::copyDataset(yawDataset(), dir);
  std::ifstream in(dir / "timestamps.txt");
  std::ostringstream out;
  std::string name;
  double t = 0.0;
  for (int k = 0; in >> name >> t; ++k) {
    if (k >= from)
      out << name << ' ' << std::fixed << t << '\n';
    else
      fs::remove(dir / "frames" / name);
  }
  testing::writeText(dir / "timestamps.txt", out.str());
}

/// The text a daemon wrote to its log (a temporary file).
std::string logText(std::FILE* log) {
  std::fflush(log);
  std::rewind(log);
  std::string text;
  for (int c; (c = std::fgetc(log)) != EOF;) text += static_cast<char>(c);
  return text;
}

TEST(DaemonMap, TheMapIsSavedAtShutdownAndARestartFindsTheHeadingInIt) {
  TempDir tmp("daemon-map");
  // The yaw dataset turns 1-6 degrees a frame: compared on every frame however fast it turns.
  // Saved every 50 ms while running (the saver thread), and at shutdown.
  const std::string map_section = "loop_closure:\n  map_file: " + (tmp / "robot.map").string() +
                                  "\n  save_interval_s: 0.05\n  check_interval: 1\n"
                                  "  max_turn_rate_deg_s: 5000\n";
  Bus first;
  std::map<double, Eigen::Matrix3d> first_map;  // by source timestamp
  {
    std::FILE* log = std::tmpfile();
    Daemon d(parseConfig(testing::fileSourceConfig(yawDataset(), "", false) + map_section), log,
             nullptr, first.sink(), lossless());
    first.run(d, 60s);
    d.join();
    EXPECT_GE(d.stats().maps_saved, 2) << "while running and at shutdown";
    EXPECT_EQ(d.stats().map_save_failures, 0);
    ASSERT_FALSE(first.statuses.empty());
    EXPECT_TRUE(first.statuses.back().final);
    EXPECT_EQ(first.statuses.back().maps_saved, d.stats().maps_saved)
        << "the final status counts the save at shutdown too";
    EXPECT_EQ(first.statuses.back().map_save_failures, 0);
    for (const pose_t& p : first.poses) EXPECT_FALSE(p.relocalising) << "no map was loaded";
    const std::string text = logText(log);
    std::fclose(log);
    EXPECT_THAT(text, ::testing::HasSubstr("none yet; starting with an empty map"));
    EXPECT_THAT(text, ::testing::HasSubstr("places saved"));
  }
  for (const pose_t& p : first.poses)
    first_map[p.source_timestamp] =
        Eigen::Quaterniond(p.map_orientation[0], p.map_orientation[1], p.map_orientation[2],
                           p.map_orientation[3])
            .toRotationMatrix();
  map::MapSnapshot saved;
  ASSERT_TRUE(map::loadMap(tmp / "robot.map", Calibration{}, 128, saved));
  ASSERT_GE(saved.place_count, 1);

  // Started again in the middle of the same turn: the odometry begins at the identity there,
  // 8 frames of heading away from where the map began.
  datasetFrom(tmp / "later", 8);
  Bus second;
  std::FILE* log = std::tmpfile();
  {
    Daemon d(parseConfig(testing::fileSourceConfig(tmp / "later", "", false) + map_section), log,
             nullptr, second.sink(), lossless());
    second.run(d, 60s);
  }
  const std::string text = logText(log);
  std::fclose(log);
  EXPECT_THAT(text, ::testing::HasSubstr("places loaded"));
  EXPECT_THAT(text, ::testing::HasSubstr("recognised place"));
  ASSERT_EQ(second.poses.size(), static_cast<std::size_t>(kFrames - 8));
  int closed_at = -1;
  double worst_heading = 0.0;
  for (std::size_t k = 0; k < second.poses.size(); ++k) {
    const pose_t& p = second.poses[k];
    const Eigen::Matrix3d map_rotation =
        Eigen::Quaterniond(p.map_orientation[0], p.map_orientation[1], p.map_orientation[2],
                           p.map_orientation[3])
            .toRotationMatrix();
    if (closed_at < 0 && p.loop_closed) closed_at = static_cast<int>(k);
    SCOPED_TRACE("frame " + std::to_string(p.source_index));
    EXPECT_EQ(p.relocalising, closed_at < 0) << "pose_t says whether the map is found";
    if (closed_at < 0) {
      EXPECT_LT(testing::rotationError(map_rotation, testing::poseRotation(p)), 1e-9)
          << "the map pose is the odometry's until the map is found";
    } else {
      ASSERT_TRUE(first_map.contains(p.source_timestamp));
      const double error = testing::rotationError(map_rotation, first_map[p.source_timestamp]);
      worst_heading = std::max(worst_heading, error);
      EXPECT_LT(error, 0.1 * std::numbers::pi / 180.0) << "the heading in the map is the first run's";
    }
  }
  ::testing::Test::RecordProperty("closed_at_frame", closed_at);
  ::testing::Test::RecordProperty("worst_heading_after_rad", std::to_string(worst_heading));
  EXPECT_GE(closed_at, 0) << "the saved map was not recognised";
  EXPECT_LE(closed_at, 5) << "three matches on three checked frames";
  // The status says what the map made of the frames: the matches that found the place, and
  // every registration ending in exactly one verdict.
  ASSERT_FALSE(second.statuses.empty());
  const status_t& s = second.statuses.back();
  EXPECT_TRUE(s.final);
  EXPECT_GE(s.loops_closed, 1);
  EXPECT_GE(s.map_verified, LoopClosureOptions{}.confirmations);
  EXPECT_EQ(s.map_registrations, s.map_verified + s.map_refused_no_heading +
                                     s.map_refused_turned + s.map_refused_fit +
                                     s.map_refused_too_far);
  EXPECT_EQ(s.map_disagreed, 0) << "the places of one spot agree on where the robot is";
  ::testing::Test::RecordProperty("map_registrations", std::to_string(s.map_registrations));
  ::testing::Test::RecordProperty("map_verified", std::to_string(s.map_verified));
}

TEST(DaemonMap, ADamagedMapOrOneOfAnotherLensIsKeptAsideAndAForeignFileIsNeverOverwritten) {
  TempDir tmp("daemon-map-refused");
  const auto run = [&](const fs::path& map_file) {
    // Compared on every frame however fast the yaw dataset turns, so the map has places.
    const std::string config = testing::fileSourceConfig(yawDataset(), "", false) +
                               "loop_closure:\n  map_file: " + map_file.string() +
                               "\n  save_interval_s: 0\n  check_interval: 1\n"
                               "  max_turn_rate_deg_s: 5000\n";
    std::FILE* log = std::tmpfile();
    Bus bus;
    daemon::DaemonStats stats;
    {
      Daemon d(parseConfig(config), log, nullptr, bus.sink(), lossless());
      bus.run(d, 60s);
      d.join();
      stats = d.stats();
    }
    EXPECT_EQ(bus.poses.size(), static_cast<std::size_t>(kFrames)) << "the daemon ran";
    std::string text = logText(log);
    std::fclose(log);
    return std::make_pair(stats, text);
  };
  // A map cut short: refused by name, kept aside, a new map saved.
  testing::writeText(tmp / "damaged.map", "OMNIPOSE MAP\n\x01\x00");
  const auto [damaged_stats, damaged_log] = run(tmp / "damaged.map");
  EXPECT_THAT(damaged_log, ::testing::HasSubstr((tmp / "damaged.map").string() + " refused"));
  EXPECT_THAT(damaged_log, ::testing::HasSubstr("kept as " + (tmp / "damaged.map.refused").string()));
  EXPECT_TRUE(fs::exists(tmp / "damaged.map.refused"));
  EXPECT_EQ(damaged_stats.maps_saved, 1);
  map::MapSnapshot saved;
  EXPECT_TRUE(map::loadMap(tmp / "damaged.map", Calibration{}, 128, saved));
  // The map just saved, as if made under a lens whose centre is 5 pixels to the right:
  // refused by name and why, kept aside, a new map saved.
  ASSERT_GE(saved.place_count, 1);
  for (std::size_t i = 0; i < saved.lens.xy.size(); i += 2) saved.lens.xy[i] += 5.0f;
  ASSERT_TRUE(map::saveMap(tmp / "other_lens.map", saved));
  const auto [lens_stats, lens_log] = run(tmp / "other_lens.map");
  EXPECT_THAT(lens_log, ::testing::HasSubstr((tmp / "other_lens.map").string() + " refused"));
  EXPECT_THAT(lens_log, ::testing::HasSubstr("made with another calibration"));
  EXPECT_TRUE(fs::exists(tmp / "other_lens.map.refused"));
  EXPECT_EQ(lens_stats.maps_saved, 1);
  // Someone else's file: refused, left as it was, nothing saved over it.
  testing::writeText(tmp / "notes.txt", "not a map\n");
  const auto [foreign_stats, foreign_log] = run(tmp / "notes.txt");
  EXPECT_THAT(foreign_log, ::testing::HasSubstr("not an omnipose map and is left alone"));
  EXPECT_EQ(foreign_stats.maps_saved, 0);
  EXPECT_EQ(testing::readText(tmp / "notes.txt"), "not a map\n");
}

TEST(DaemonMap, ALoadedMapNoFrameRecognisesIsKeptAsideBeforeANewMapIsSavedOverIt) {
  // MapKeeper's part: the odometry's dropping of an unrecognised map (LoopClosure, tested in
  // MapOfSphereViews) is given as the results it reports: relocalising, then not, without a
  // loop closed on that frame.
  TempDir tmp("daemon-map-unrecognised");
  const std::vector<cv::Mat> frames = testing::renderFrames("translate", 10);
  OdometryOptions options;
  options.pipeline.threads = 1;
  MapFileConfig config;
  config.path = tmp / "robot.map";
  config.save_interval_s = 0.0;
  {
    Odometry odometry(Calibration{}, options);
    daemon::StatusBoard board(nullptr);
    daemon::MapKeeper keeper(config, options.loop_closure.max_places, board);
    keeper.load(odometry, Calibration{});
    for (std::size_t k = 0; k < frames.size(); ++k)
      ASSERT_TRUE(odometry.process(frames[k], {k / 30.0}));
    ASSERT_TRUE(keeper.saveNow(odometry));
  }
  ASSERT_FALSE(testing::readText(config.path).empty());
  const auto restart = [&](bool recognised) {
    std::FILE* log = std::tmpfile();
    daemon::StatusBoard board(log);
    {
      Odometry odometry(Calibration{}, options);
      daemon::MapKeeper keeper(config, options.loop_closure.max_places, board);
      keeper.load(odometry, Calibration{});
      OdometryResult r;
      r.relocalising = true;
      keeper.afterFrame(odometry, r, 1, SteadyClock::now());
      r.relocalising = false;
      r.loop_closed = recognised;
      r.loop_place_sequence = recognised ? 4 : -1;
      keeper.afterFrame(odometry, r, 2, SteadyClock::now());
      EXPECT_TRUE(keeper.saveNow(odometry));
    }
    std::string text = logText(log);
    std::fclose(log);
    return text;
  };

  const std::string found_log = restart(true);
  EXPECT_THAT(found_log, HasSubstr("frame 2 recognised place 4 of the loaded map"));
  EXPECT_FALSE(fs::exists(tmp / "robot.map.unrecognised"));

  const std::string loaded_map = testing::readText(config.path);  // as the last run saved it
  const std::string dropped_log = restart(false);
  EXPECT_THAT(dropped_log, HasSubstr("no place of it recognised by frame 2"));
  EXPECT_THAT(dropped_log, HasSubstr("kept as " + (tmp / "robot.map.unrecognised").string()));
  EXPECT_TRUE(testing::readText(tmp / "robot.map.unrecognised") == loaded_map)
      << "the loaded map, byte for byte";
  map::MapSnapshot saved;
  EXPECT_TRUE(map::loadMap(config.path, Calibration{}, options.loop_closure.max_places, saved))
      << "the new map is saved in its place";
}

TEST(DaemonFaults, FailedPublishesAreCountedInThePublishedStatus) {
  constexpr int kTotal = 12;
  const auto frames = testing::renderFrames("yaw", 6);
  Bus bus;
  const auto config = parseConfig("source: {type: file, path: /nonexistent}\ncalibration: " +
                                  (yawDataset() / "calibration.yaml").string() +
                                  "\nlcm: {status_hz: 20}\n");
  testing::MemorySource::Script script;
  script.total = kTotal;
  script.period = 20ms;  // long enough for a few periodic statuses
  Daemon d(config, stderr, std::make_unique<testing::MemorySource>(frames, script),
           std::make_unique<FailingChannelSink>(bus.lcm, "OMNI_POSE"),
           lossless());
  bus.run(d, 60s);

  EXPECT_TRUE(bus.poses.empty()) << "every pose was refused";
  ASSERT_GE(bus.statuses.size(), 2u);
  const status_t& last = bus.statuses.back();
  EXPECT_TRUE(last.final);
  EXPECT_EQ(last.frames_processed, kTotal);
  EXPECT_EQ(last.publish_failures, kTotal) << "one per refused pose; every status went out";
  EXPECT_EQ(d.stats().publish_failures, kTotal);
  EXPECT_THAT(last.last_error, HasSubstr("channel OMNI_POSE"));
  EXPECT_THAT(last.last_error, HasSubstr("test sink refuses the channel"));
  bool periodic_carried_it = false;  // not only the final status
  for (std::size_t k = 1; k < bus.statuses.size(); ++k) {
    EXPECT_GE(bus.statuses[k].publish_failures, bus.statuses[k - 1].publish_failures);
    if (!bus.statuses[k].final && bus.statuses[k].publish_failures > 0) periodic_carried_it = true;
  }
  EXPECT_TRUE(periodic_carried_it);
  expectEveryFrameCountedOnce(last, kTotal);
}

}  // namespace
}  // namespace omnipose
