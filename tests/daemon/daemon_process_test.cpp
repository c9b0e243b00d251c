// omniposed and omnipose-listen as a user runs them: a dataset rendered with omnipose-synth,
// the daemon writing a file:// LCM log, every message decoded with the generated types and
// checked against ground truth; real-time replay timing; bad configuration; SIGINT/SIGTERM;
// a corrupt frame; lcm-logger recording the daemon's udpm traffic in a private network
// namespace (never any multicast outside it).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/un.h>

#include <algorithm>
#include <csignal>
#include <cstring>
#include <thread>

#include "bad_images.hpp"
#include "daemon_test_support.hpp"
#include "test_figures.hpp"

using ::testing::HasSubstr;

namespace omnipose {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;
using testing::TempDir;

constexpr int kFrames = 30;

fs::path omniposed() { return testing::binaryDir() / "omniposed"; }

/// A 30-frame rotation sequence (preset mixed: random axes, up to 12 deg per frame),
/// rendered with the omnipose-synth tool, shared by every test (read-only; tests that
/// damage it work on a copy).
const fs::path& mixedDataset() {
  const fs::path synth = testing::binaryDir() / "omnipose-synth";
  static const fs::path path = testing::cachedDataset(
      "mixed" + std::to_string(kFrames),
      [&](const fs::path& out) {
        TempDir logs("synth");
        const int rc = testing::runProcess(
            {synth.string(), "--texture", testing::indoorPhoto().string(), "--out", out.string(),
             "--preset", "mixed", "--frames", std::to_string(kFrames), "--seed", "5",
             "--supersample", "1"},
            logs / "synth.out", logs / "synth.err", 300s);
        if (rc != 0)
          throw std::runtime_error("omnipose-synth failed: " + testing::readText(logs / "synth.err"));
      },
      synth);
  return path;
}

struct DaemonRun {
  int exit_code = -1;
  std::string err;
  testing::DecodedLog log;
};

/// Runs omniposed on `config_text` to completion.
DaemonRun runDaemon(const TempDir& tmp, const std::string& config_text, const fs::path& lcm_log,
              std::chrono::seconds timeout = 120s) {
  testing::writeText(tmp / "daemon.yaml", config_text);
  DaemonRun r;
  r.exit_code = testing::runProcess({omniposed().string(), "--config", (tmp / "daemon.yaml").string()},
                                    tmp / "out.txt", tmp / "err.txt", timeout);
  r.err = testing::readText(tmp / "err.txt");
  if (!lcm_log.empty() && fs::exists(lcm_log)) r.log = testing::readLcmLog(lcm_log);
  return r;
}

std::string logUrl(const fs::path& path) { return "file://" + path.string() + "?mode=w"; }

TEST(Omniposed, EndToEndFileLogDecodesAndMatchesGroundTruth) {
  TempDir tmp("e2e");
  const fs::path& data = mixedDataset();
  const fs::path lcm_log = tmp / "run.lcm";
  const auto t_start_us = std::chrono::duration_cast<std::chrono::microseconds>(
                              std::chrono::system_clock::now().time_since_epoch()).count();
  const DaemonRun r = runDaemon(tmp, testing::fileSourceConfig(data, logUrl(lcm_log), /*realtime=*/false,
                                                         false, "  fit_channel: OMNI_FIT\n"),
                          lcm_log);
  const auto t_end_us = std::chrono::duration_cast<std::chrono::microseconds>(
                            std::chrono::system_clock::now().time_since_epoch()).count();
  ASSERT_EQ(r.exit_code, 0) << r.err;
  // The effective configuration is logged at start-up.
  EXPECT_THAT(r.err, HasSubstr("effective values"));
  EXPECT_THAT(r.err, HasSubstr("window: 110"));
  EXPECT_THAT(r.err, HasSubstr("status_channel: OMNI_STATUS"));

  const testing::DecodedLog& log = r.log;
  EXPECT_EQ(log.undecodable, 0);
  EXPECT_EQ(log.channels, (std::set<std::string>{"OMNI_POSE", "OMNI_STATUS", "OMNI_FIT"}));
  ASSERT_EQ(log.poses.size(), static_cast<std::size_t>(kFrames));
  EXPECT_EQ(log.diagnostics.size(), static_cast<std::size_t>(kFrames - 1));

  const auto stamps = testing::readTimestamps(data);
  const auto gt = readTum(data / "groundtruth.tum");
  ASSERT_EQ(gt.size(), static_cast<std::size_t>(kFrames));
  double max_pair_error = 0, max_chain_error = 0;
  for (int k = 0; k < kFrames; ++k) {
    const pose_t& p = log.poses[static_cast<std::size_t>(k)];
    EXPECT_EQ(p.sequence, k);
    EXPECT_EQ(p.source_index, k);
    EXPECT_DOUBLE_EQ(p.source_timestamp, stamps.at(testing::frameName(k)));
    EXPECT_GE(p.utime, t_start_us);
    EXPECT_LE(p.utime, t_end_us);
    EXPECT_LE(p.utime, log.pose_log_utime[static_cast<std::size_t>(k)]) << "captured before published";
    EXPECT_EQ(p.segment, 0);
    EXPECT_EQ(p.frames_skipped, 0);
    if (k == 0) {
      EXPECT_EQ(p.status, pose_t::STATUS_LOST);
      EXPECT_EQ(p.reference_sequence, -1);
      continue;
    }
    EXPECT_GT(p.utime, log.poses[static_cast<std::size_t>(k - 1)].utime);
    EXPECT_EQ(p.status, pose_t::STATUS_OK) << k;
    EXPECT_EQ(p.reference_sequence, k - 1);
    const Eigen::Matrix3d gt_rel = (gt[k - 1].pose.inverse() * gt[k].pose).rotation();
    const double pair_error = testing::rotationError(testing::relativeRotation(p), gt_rel);
    EXPECT_LT(pair_error, 0.003) << "pair " << k - 1 << " -> " << k;
    max_pair_error = std::max(max_pair_error, pair_error);
    const double chain_error = testing::rotationError(testing::poseRotation(p), gt[k].pose.rotation());
    max_chain_error = std::max(max_chain_error, chain_error);
    // Covariance: symmetric, positive diagonal.
    for (int i = 0; i < 6; ++i) {
      EXPECT_GT(p.covariance[i * 7], 0.0);
      for (int j = 0; j < 6; ++j) EXPECT_NEAR(p.covariance[i * 6 + j], p.covariance[j * 6 + i], 1e-12);
    }
  }
  EXPECT_LT(max_chain_error, 0.02) << "chained orientation after " << kFrames << " frames";
  testing::recordFigure("max_pair_error_rad", max_pair_error, 5);
  testing::recordFigure("max_chained_error_rad", max_chain_error, 5);
  RecordProperty("frames", kFrames);

  // Status: at least the final one, which is the last message of the log.
  ASSERT_FALSE(log.statuses.empty());
  const status_t& last = log.statuses.back();
  EXPECT_TRUE(last.final);
  EXPECT_EQ(log.order.back().channel, "OMNI_STATUS");
  EXPECT_EQ(last.frames_received, kFrames);
  EXPECT_EQ(last.frames_processed, kFrames);
  EXPECT_EQ(last.frames_skipped_stale, 0);
  EXPECT_EQ(last.frames_bad, 0);
  EXPECT_EQ(last.poses_lost, 1);
  EXPECT_EQ(last.source_state, status_t::SOURCE_ENDED);
  EXPECT_THAT(last.source, HasSubstr(data.string()));
  EXPECT_TRUE(last.last_error.empty()) << last.last_error;

  // The listener, as a user runs it, prints every pose from the log.
  const int rc = testing::runProcess(
      {(testing::binaryDir() / "omnipose-listen").string(), "--url",
       "file://" + lcm_log.string() + "?speed=0", "--count", std::to_string(kFrames), "--timeout", "20"},
      tmp / "listen.out", tmp / "listen.err", 60s);
  EXPECT_EQ(rc, 0) << testing::readText(tmp / "listen.err");
  const std::string printed = testing::readText(tmp / "listen.out");
  int pose_lines = 0;
  for (std::size_t at = printed.find("pose seq "); at != std::string::npos; at = printed.find("pose seq ", at + 1))
    ++pose_lines;
  EXPECT_EQ(pose_lines, kFrames) << printed;
  EXPECT_THAT(printed, HasSubstr("pose seq 29 "));

  // --tum: every pose's chained pose at its recorded timestamp, as published.
  const int tum_rc = testing::runProcess(
      {(testing::binaryDir() / "omnipose-listen").string(), "--url",
       "file://" + lcm_log.string() + "?speed=0", "--status-channel", "", "--tum",
       (tmp / "poses.tum").string()},
      tmp / "listen-tum.out", tmp / "listen-tum.err", 60s);
  EXPECT_EQ(tum_rc, 0) << testing::readText(tmp / "listen-tum.err");
  const auto written = readTum(tmp / "poses.tum");
  ASSERT_EQ(written.size(), static_cast<std::size_t>(kFrames));
  for (int k = 0; k < kFrames; ++k) {
    const pose_t& p = log.poses[static_cast<std::size_t>(k)];
    EXPECT_NEAR(written[k].timestamp, p.source_timestamp, 5e-7) << k;
    EXPECT_LT(testing::rotationError(written[k].pose.rotation(), testing::poseRotation(p)), 1e-9) << k;
    for (int i = 0; i < 3; ++i) EXPECT_NEAR(written[k].pose.translation()[i], p.position[i], 1e-6) << k;
  }
  EXPECT_EQ(testing::runProcess({(testing::binaryDir() / "omnipose-listen").string(), "--url",
                                 "file://" + lcm_log.string() + "?speed=0", "--tum",
                                 "/nonexistent/dir/poses.tum"},
                                tmp / "listen-bad.out", tmp / "listen-bad.err", 60s),
            1);
  EXPECT_THAT(testing::readText(tmp / "listen-bad.err"),
              HasSubstr("/nonexistent/dir/poses.tum: cannot write"));
  // A log that is a FIFO without a writer would block LCM's file provider: refused at once.
  ASSERT_EQ(::mkfifo((tmp / "fifo.lcm").c_str(), 0600), 0);
  EXPECT_EQ(testing::runProcess({(testing::binaryDir() / "omnipose-listen").string(), "--url",
                                 "file://" + (tmp / "fifo.lcm").string() + "?speed=0"},
                                tmp / "listen-fifo.out", tmp / "listen-fifo.err", 10s),
            1);
  EXPECT_THAT(testing::readText(tmp / "listen-fifo.err"),
              HasSubstr("fifo.lcm: not a regular file (a FIFO)"));
}

TEST(Omniposed, AThirtyTwoThousandPixelPngCostsTheDaemonAndTheReplayNoMemory) {
  // A complete, valid 32000 x 32000 PNG (about 1 MB of file, 1 GB of pixels) in the middle of
  // the recording: refused from its header, so the peak RSS stays near a normal run's.
  TempDir tmp("bomb-rss");
  // The first 12 frames of the recording, with and without the PNG after frame 10.
  const auto firstFrames = [&](const fs::path& to) {
    testing::copyDataset(mixedDataset(), to);
    const auto stamps = testing::readTimestamps(to);
    for (int k = 12; k < kFrames; ++k) fs::remove(to / "frames" / testing::frameName(k));
    fs::remove(to / "groundtruth.tum");
    testing::writeTimestamps(to, 12, [&](int k) { return stamps.at(testing::frameName(k)); });
  };
  firstFrames(tmp / "normal");
  firstFrames(tmp / "bomb");
  testing::insertFrames(tmp / "bomb", 10, {{"zeros_32000.png", testing::zeroPng(32000, 32000)}});
  auto peak = [&](const std::vector<std::string>& argv, const std::string& tag, int& exit_code) {
    testing::Child child(argv, tmp / (tag + ".out"), tmp / (tag + ".err"));
    exit_code = child.wait(120s);
    return child.maxRssKb();
  };
  for (const char* program : {"omniposed", "omnipose-replay"}) {
    SCOPED_TRACE(program);
    long rss_kb[2] = {0, 0};
    for (int with_bomb = 0; with_bomb < 2; ++with_bomb) {
      const fs::path data = tmp / (with_bomb ? "bomb" : "normal");
      const std::string tag = std::string(program) + (with_bomb ? "-bomb" : "-normal");
      std::vector<std::string> argv;
      if (std::string(program) == "omniposed") {
        testing::writeText(tmp / (tag + ".yaml"),
                           testing::fileSourceConfig(data, logUrl(tmp / (tag + ".lcm")), false));
        argv = {omniposed().string(), "--config", (tmp / (tag + ".yaml")).string()};
      } else {
        argv = {(testing::binaryDir() / "omnipose-replay").string(), data.string()};
      }
      int exit_code = -1;
      rss_kb[with_bomb] = peak(argv, tag, exit_code);
      ASSERT_EQ(exit_code, 0) << testing::readText(tmp / (tag + ".err"));
      if (with_bomb) {
        EXPECT_THAT(testing::readText(tmp / (tag + ".err")),
                    HasSubstr("32000x32000, expected 720x720"));
      }
    }
    RecordProperty(std::string(program) + "_peak_rss_kb_normal", std::to_string(rss_kb[0]));
    RecordProperty(std::string(program) + "_peak_rss_kb_bomb", std::to_string(rss_kb[1]));
    EXPECT_GT(rss_kb[0], 0);
    EXPECT_LT(rss_kb[1], 2 * rss_kb[0]) << "peak RSS in kB, normal run " << rss_kb[0];
  }
}

TEST(Omniposed, RealtimeReplayAt30FpsKeepsTheRecordedTimingAndReportsLatency) {
  TempDir tmp("rt30");
  const fs::path& data = mixedDataset();
  const fs::path lcm_log = tmp / "run.lcm";
  const DaemonRun r = runDaemon(tmp, testing::fileSourceConfig(data, logUrl(lcm_log), /*realtime=*/true), lcm_log);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  const testing::DecodedLog& log = r.log;
  ASSERT_FALSE(log.poses.empty());
  ASSERT_FALSE(log.statuses.empty());
  const status_t& last = log.statuses.back();
  EXPECT_TRUE(last.final);
  // Each frame is processed, skipped as stale, not believed, or (source running late) never
  // read. On a starved machine (a sanitizer build beside other tests) most frames go stale,
  // and a frame far from the last processed one can be too different to be believed.
  EXPECT_EQ(last.frames_received, kFrames);
  EXPECT_EQ(last.frames_processed + last.frames_skipped_stale + last.frames_bad +
                last.frames_lost_upstream,
            last.frames_received)
      << r.err;
  EXPECT_EQ(static_cast<std::int64_t>(log.poses.size()), last.frames_processed);
  EXPECT_EQ(log.poses.back().source_index, kFrames - 1) << "the last frame is always processed";
  // Capture stamps follow the recording: (t_k - t_0) of timestamps.txt on the wall clock.
  const pose_t& first = log.poses.front();
  for (const pose_t& p : log.poses) {
    EXPECT_NEAR(static_cast<double>(p.utime - first.utime),
                (p.source_timestamp - first.source_timestamp) * 1e6, 2.0);
  }
  RecordProperty("frames", kFrames);
  RecordProperty("frames_processed", static_cast<int>(last.frames_processed));
  RecordProperty("frames_skipped_stale", static_cast<int>(last.frames_skipped_stale));
  RecordProperty("frames_not_read_in_time", static_cast<int>(last.frames_lost_upstream));
  testing::recordFigure("processing_ms_p50", last.processing_ms_p50, 1);
  testing::recordFigure("processing_ms_p99", last.processing_ms_p99, 1);
  testing::recordFigure("latency_ms_p50", last.latency_ms_p50, 1);
  testing::recordFigure("latency_ms_p99", last.latency_ms_p99, 1);
  EXPECT_GT(last.processing_ms_p50, 0.0f);
  EXPECT_GE(last.latency_ms_p50, last.processing_ms_p50 * 0.5f);
  // Fresh pose, not a backlog: the latency is bounded by about two processing times.
  EXPECT_LT(last.latency_ms_p99, 2.0f * last.processing_ms_p99 + 100.0f);
}

TEST(Omniposed, BadConfigurationReportsEveryProblemAndExitsNonZero) {
  TempDir tmp("badcfg");
  testing::writeText(tmp / "daemon.yaml",
                     "source: {type: file, path: /data, speed: 2}\n"
                     "calibration: cal.yaml\n"
                     "input: fisheye\n"
                     "pipeline: {step: -3}\n"
                     "lcm: {status_hz: 0, pose_chanel: X}\n"
                     "extra: 1\n");
  const int rc = testing::runProcess({omniposed().string(), "--config", (tmp / "daemon.yaml").string()},
                                     tmp / "out", tmp / "err", 30s);
  const std::string err = testing::readText(tmp / "err");
  EXPECT_EQ(rc, 1) << err;
  for (const char* needle : {"source.speed", "input", "fisheye", "pipeline.", "step", "lcm.status_hz",
                             "lcm.pose_chanel", "extra"}) {
    EXPECT_THAT(err, HasSubstr(needle)) << "missing '" << needle << "' in:\n" << err;
  }
  // A missing file and a missing argument.
  EXPECT_EQ(testing::runProcess({omniposed().string(), "--config", (tmp / "none.yaml").string()},
                                tmp / "out", tmp / "err", 30s),
            1);
  EXPECT_THAT(testing::readText(tmp / "err"), HasSubstr("none.yaml"));
  EXPECT_EQ(testing::runProcess({omniposed().string()}, tmp / "out", tmp / "err", 30s), 2);
  // A valid file whose source is missing: start-up fails naming it.
  testing::writeText(tmp / "daemon.yaml",
                     testing::fileSourceConfig(tmp / "no-such-dataset", "memq://", false));
  Calibration{}.save(tmp / "no-such-dataset-cal.yaml");
  EXPECT_EQ(testing::runProcess({omniposed().string(), "--config", (tmp / "daemon.yaml").string()},
                                tmp / "out", tmp / "err", 30s),
            1);
  EXPECT_THAT(testing::readText(tmp / "err"), HasSubstr("start-up failed"));
  // Scheduling that cannot be had stops the start-up, named, before anything runs.
  testing::writeText(tmp / "daemon.yaml",
                     testing::fileSourceConfig(mixedDataset(), "memq://", false) +
                         "scheduling: {cpus: [4000]}\n");
  EXPECT_EQ(testing::runProcess({omniposed().string(), "--config", (tmp / "daemon.yaml").string()},
                                tmp / "out", tmp / "err", 30s),
            1);
  const std::string refused = testing::readText(tmp / "err");
  EXPECT_THAT(refused, HasSubstr("start-up failed: scheduling refused:"));
  EXPECT_THAT(refused, HasSubstr("daemon.yaml: scheduling.cpus: CPU 4000 does not exist"));
}

void expectCleanStopOn(int sig, const char* name) {
  TempDir tmp(std::string("sig") + name);
  const fs::path lcm_log = tmp / "run.lcm";
  // An endless source: the recording looped in real time.
  testing::writeText(tmp / "daemon.yaml",
                     testing::fileSourceConfig(mixedDataset(), logUrl(lcm_log), /*realtime=*/true,
                                               /*loop=*/true, "  status_hz: 5\n"));
  testing::Child child({omniposed().string(), "--config", (tmp / "daemon.yaml").string()},
                       tmp / "out", tmp / "err");
  // Wait until it runs (start-up logged), then let it work for a while.
  const auto deadline = std::chrono::steady_clock::now() + 60s;
  while (testing::readText(tmp / "err").find("systemd notify") == std::string::npos &&
         std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(50ms);
  std::this_thread::sleep_for(2s);
  ASSERT_TRUE(child.running()) << testing::readText(tmp / "err");
  child.signal(sig);
  const int rc = child.wait(15s);
  const std::string err = testing::readText(tmp / "err");
  ASSERT_EQ(rc, 0) << name << ":\n" << err;
  EXPECT_THAT(err, HasSubstr(std::string(name) + " received"));
  EXPECT_THAT(err, HasSubstr("stopped:"));
  const auto log = testing::readLcmLog(lcm_log);
  EXPECT_GT(log.poses.size(), 3u);
  ASSERT_FALSE(log.statuses.empty());
  EXPECT_EQ(log.order.back().channel, "OMNI_STATUS") << "the final status is the last message";
  const status_t& last = log.statuses.back();
  EXPECT_TRUE(last.final);
  EXPECT_EQ(last.source_state, status_t::SOURCE_STOPPED);
  EXPECT_EQ(last.frames_processed, static_cast<std::int64_t>(log.poses.size()));
}

TEST(Omniposed, SigintStopsCleanlyWithAFinalStatus) { expectCleanStopOn(SIGINT, "SIGINT"); }
TEST(Omniposed, SigtermStopsCleanlyWithAFinalStatus) { expectCleanStopOn(SIGTERM, "SIGTERM"); }

TEST(Omniposed, KeepsRunningThroughACorruptFrameAndEndsWithExitZero) {
  TempDir tmp("corrupt");
  testing::copyDataset(mixedDataset(), tmp / "d");
  testing::writeText(tmp / "d/frames/000011.png", "\x89PNG truncated");
  const fs::path lcm_log = tmp / "run.lcm";
  const DaemonRun r = runDaemon(tmp, testing::fileSourceConfig(tmp / "d", logUrl(lcm_log), false), lcm_log);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_THAT(r.err, HasSubstr("000011.png")) << "the fault is logged naming the file:\n" << r.err;
  ASSERT_EQ(r.log.poses.size(), static_cast<std::size_t>(kFrames - 1));
  const status_t& last = r.log.statuses.back();
  EXPECT_EQ(last.frames_bad, 1);
  EXPECT_THAT(last.last_error, HasSubstr("000011.png"));
  // The frame after the corrupt one is registered against the keyframe: the chain goes on.
  for (const pose_t& p : r.log.poses) {
    EXPECT_EQ(p.segment, 0);
    if (p.source_index == 12) {
      EXPECT_NE(p.status, pose_t::STATUS_LOST);
      EXPECT_EQ(p.track_state, pose_t::TRACK_BRIDGED);
      EXPECT_EQ(p.reference_sequence, p.sequence - 2);
    }
    if (p.source_index > 12) {
      EXPECT_EQ(p.reference_sequence, p.sequence - 1);
    }
  }
}

TEST(Omniposed, NotifiesSystemdReadyWatchdogAndStopping) {
  TempDir tmp("notify");
  // Play systemd's part: a datagram socket at NOTIFY_SOCKET, WatchdogSec = 0.4 s.
  const fs::path socket_path = tmp / "notify.sock";
  const int sock = socket(AF_UNIX, SOCK_DGRAM | SOCK_NONBLOCK | SOCK_CLOEXEC, 0);
  ASSERT_GE(sock, 0);
  sockaddr_un addr{};
  addr.sun_family = AF_UNIX;
  std::snprintf(addr.sun_path, sizeof(addr.sun_path), "%s", socket_path.c_str());
  ASSERT_EQ(bind(sock, reinterpret_cast<sockaddr*>(&addr), sizeof(addr)), 0);
  const fs::path lcm_log = tmp / "run.lcm";
  testing::writeText(tmp / "daemon.yaml",
                     testing::fileSourceConfig(mixedDataset(), logUrl(lcm_log), /*realtime=*/true,
                                               /*loop=*/true));
  std::vector<std::string> messages;
  auto receive = [&] {
    char buf[4096];
    for (;;) {
      const ssize_t n = recv(sock, buf, sizeof(buf), 0);
      if (n <= 0) break;
      messages.emplace_back(buf, static_cast<std::size_t>(n));
    }
  };
  {
    testing::Child child({omniposed().string(), "--config", (tmp / "daemon.yaml").string()},
                         tmp / "out", tmp / "err",
                         {"NOTIFY_SOCKET=" + socket_path.string(), "WATCHDOG_USEC=400000"});
    const auto deadline = std::chrono::steady_clock::now() + 60s;
    while (std::chrono::steady_clock::now() < deadline) {
      receive();
      if (std::count_if(messages.begin(), messages.end(),
                        [](const std::string& m) { return m == "WATCHDOG=1"; }) >= 4)
        break;
      std::this_thread::sleep_for(50ms);
    }
    const std::string err = testing::readText(tmp / "err");
    if (err.find("systemd notify: not built in") != std::string::npos) {
      close(sock);
      GTEST_SKIP() << "omniposed was built without libsystemd (OMNIPOSE_WITH_SYSTEMD)";
    }
    child.signal(SIGTERM);
    ASSERT_EQ(child.wait(15s), 0) << testing::readText(tmp / "err");
  }
  receive();
  close(sock);
  ASSERT_FALSE(messages.empty());
  EXPECT_EQ(messages.front().rfind("READY=1", 0), 0u) << messages.front();
  EXPECT_GE(std::count(messages.begin(), messages.end(), std::string("WATCHDOG=1")), 4);
  EXPECT_EQ(messages.back(), "STOPPING=1");
}

/// "unshare -rn" (or "-n" as root) when this system allows network namespaces.
std::vector<std::string> unshareCommand(const TempDir& tmp) {
  for (const char* flags : {"-rn", "-n"}) {
    if (testing::runProcess({"/usr/bin/unshare", flags, "/bin/true"}, tmp / "u.out", tmp / "u.err", 10s) == 0)
      return {"/usr/bin/unshare", flags};
  }
  return {};
}

TEST(Omniposed, LcmLoggerRecordsTheDaemonOnAPrivateNetwork) {
  TempDir tmp("logger");
  if (!fs::exists("/usr/bin/lcm-logger")) GTEST_SKIP() << "lcm-logger (liblcm-bin) not installed";
  const auto unshare = unshareCommand(tmp);
  if (unshare.empty()) {
    GTEST_SKIP() << "network namespaces are not allowed here (unshare -rn / -n failed: "
                 << testing::readText(tmp / "u.err") << "); multicast is never sent outside one";
  }
  const std::string url = "udpm://239.255.76.67:7667?ttl=0";
  const fs::path logger_log = tmp / "logger.lcm";
  testing::writeText(tmp / "daemon.yaml",
                     testing::fileSourceConfig(mixedDataset(), url, /*realtime=*/false));
  // Inside the namespace: only loopback exists, with the multicast route on it.
  const std::string script =
      "set -e; ip link set lo up; ip route add 224.0.0.0/4 dev lo; set +e\n"
      "lcm-logger -q -f --lcm-url='" + url + "' '" + logger_log.string() + "' & L=$!\n"
      "'" + (testing::binaryDir() / "omnipose-listen").string() + "' --url '" + url +
      "' --count " + std::to_string(kFrames) + " --timeout 60 > '" + (tmp / "listen.out").string() +
      "' 2>&1 & P=$!\n"
      "sleep 1\n"
      "'" + omniposed().string() + "' --config '" + (tmp / "daemon.yaml").string() + "'; rc=$?\n"
      "wait $P; lrc=$?\n"
      "sleep 0.5; kill -INT $L; wait $L\n"
      "echo \"daemon=$rc listener=$lrc\"\n"
      "exit $rc\n";
  std::vector<std::string> argv = unshare;
  argv.insert(argv.end(), {"/bin/sh", "-c", script});
  const int rc = testing::runProcess(argv, tmp / "ns.out", tmp / "ns.err", 180s);
  const std::string out = testing::readText(tmp / "ns.out");
  ASSERT_EQ(rc, 0) << out << testing::readText(tmp / "ns.err");
  EXPECT_THAT(out, HasSubstr("listener=0"));

  // What the independent logger recorded decodes into the full run.
  const auto log = testing::readLcmLog(logger_log);
  EXPECT_EQ(log.undecodable, 0);
  ASSERT_EQ(log.poses.size(), static_cast<std::size_t>(kFrames));
  for (int k = 0; k < kFrames; ++k) EXPECT_EQ(log.poses[static_cast<std::size_t>(k)].sequence, k);
  ASSERT_FALSE(log.statuses.empty());
  EXPECT_TRUE(log.statuses.back().final);
  EXPECT_EQ(log.statuses.back().frames_processed, kFrames);
  // And the listener printed every pose live.
  const std::string printed = testing::readText(tmp / "listen.out");
  int pose_lines = 0;
  for (std::size_t at = printed.find("pose seq "); at != std::string::npos; at = printed.find("pose seq ", at + 1))
    ++pose_lines;
  EXPECT_EQ(pose_lines, kFrames) << printed;
}

// ---------------------------------------------------------------------------------------
// Faults the daemon must survive.
// ---------------------------------------------------------------------------------------

/// Starts omniposed on an endless source (the 30-frame recording looped, paced in real time)
/// and waits until it runs.
struct RunningDaemon {
  RunningDaemon(const TempDir& tmp, const std::string& lcm_url, const std::string& extra_lcm = "")
      : err_path(tmp / "err") {
    testing::writeText(tmp / "daemon.yaml",
                       testing::fileSourceConfig(mixedDataset(), lcm_url, /*realtime=*/true,
                                                 /*loop=*/true, extra_lcm));
    child = std::make_unique<testing::Child>(
        std::vector<std::string>{omniposed().string(), "--config", (tmp / "daemon.yaml").string()},
        tmp / "out", err_path);
    waitFor("systemd notify", 60s);
  }
  std::string err() const { return testing::readText(err_path); }
  /// Waits until the daemon's log contains `needle`; true if it did in time.
  bool waitFor(const std::string& needle, std::chrono::milliseconds timeout) const {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (err().find(needle) == std::string::npos) {
      if (std::chrono::steady_clock::now() > deadline) return false;
      std::this_thread::sleep_for(50ms);
    }
    return true;
  }
  fs::path err_path;
  std::unique_ptr<testing::Child> child;
};

std::size_t countOf(const std::string& text, const std::string& needle) {
  std::size_t n = 0;
  for (auto at = text.find(needle); at != std::string::npos; at = text.find(needle, at + 1)) ++n;
  return n;
}

TEST(OmniposedFaults, UnusableLcmUrlAtStartupIsAClearErrorAndExitCodeOne) {
  TempDir tmp("badurl");
  struct Case {
    std::string url;
    std::vector<std::string> says;
  };
  const std::vector<Case> cases = {
      {"nonsense://x", {"lcm.url \"nonsense://x\"", "cannot initialise LCM"}},
      {"file://" + (tmp / "no-such-dir/run.lcm").string() + "?mode=w",
       {"lcm.url", (tmp / "no-such-dir/run.lcm").string(), "its directory", "does not exist"}},
      {"file://" + tmp.path().string() + "?mode=w",
       {"lcm.url", tmp.path().string() + ": not a regular file (a directory)"}},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.url);
    const DaemonRun r = runDaemon(tmp, testing::fileSourceConfig(mixedDataset(), c.url, false), {},
                                  60s);
    EXPECT_EQ(r.exit_code, 1) << r.err;
    EXPECT_THAT(r.err, HasSubstr("start-up failed"));
    for (const auto& needle : c.says) EXPECT_NE(r.err.find(needle), std::string::npos) << r.err;
  }
}

TEST(OmniposedFaults, SighupIsLoggedWithTheCountersAndTheDaemonKeepsRunning) {
  TempDir tmp("hup");
  const fs::path lcm_log = tmp / "run.lcm";
  RunningDaemon d(tmp, logUrl(lcm_log));
  ASSERT_TRUE(d.child->running()) << d.err();
  std::this_thread::sleep_for(1s);
  d.child->signal(SIGHUP);
  ASSERT_TRUE(d.waitFor("SIGHUP received", 10s)) << d.err();
  std::this_thread::sleep_for(1s);
  EXPECT_TRUE(d.child->running()) << "SIGHUP must not stop the daemon:\n" << d.err();
  d.child->signal(SIGHUP);
  ASSERT_TRUE(d.waitFor("SIGHUP received", 10s));
  const auto hup_deadline = std::chrono::steady_clock::now() + 10s;
  while (countOf(d.err(), "SIGHUP received") < 2 && std::chrono::steady_clock::now() < hup_deadline)
    std::this_thread::sleep_for(50ms);
  const std::string before_stop = d.err();
  EXPECT_EQ(countOf(before_stop, "SIGHUP received"), 2u) << before_stop;
  EXPECT_THAT(before_stop, HasSubstr("configuration not reloaded"));
  EXPECT_THAT(before_stop, HasSubstr("processed "));
  d.child->signal(SIGTERM);
  ASSERT_EQ(d.child->wait(15s), 0) << d.err();
  const auto log = testing::readLcmLog(lcm_log);
  ASSERT_FALSE(log.statuses.empty());
  EXPECT_TRUE(log.statuses.back().final);
  EXPECT_EQ(log.statuses.back().frames_processed, static_cast<std::int64_t>(log.poses.size()));
}

TEST(OmniposedFaults, TwoSigtermsInARowStopOnceCleanly) {
  TempDir tmp("term2");
  const fs::path lcm_log = tmp / "run.lcm";
  RunningDaemon d(tmp, logUrl(lcm_log));
  std::this_thread::sleep_for(1s);
  ASSERT_TRUE(d.child->running()) << d.err();
  d.child->signal(SIGTERM);
  d.child->signal(SIGTERM);
  std::this_thread::sleep_for(20ms);
  d.child->signal(SIGTERM);
  ASSERT_EQ(d.child->wait(15s), 0) << d.err();
  const std::string err = d.err();
  EXPECT_EQ(countOf(err, "SIGTERM received"), 1u) << err;
  EXPECT_EQ(countOf(err, "stopped:"), 1u) << err;
  const auto log = testing::readLcmLog(lcm_log);
  EXPECT_EQ(log.undecodable, 0);
  ASSERT_FALSE(log.statuses.empty());
  EXPECT_EQ(log.order.back().channel, "OMNI_STATUS");
  EXPECT_TRUE(log.statuses.back().final);
  EXPECT_EQ(std::count_if(log.statuses.begin(), log.statuses.end(),
                          [](const status_t& s) { return s.final; }),
            1);
  EXPECT_EQ(log.statuses.back().frames_processed, static_cast<std::int64_t>(log.poses.size()));
}

TEST(OmniposedFaults, TimestampsGoingBackwardsAreAGapBridgedAndEveryFrameIsProcessed) {
  TempDir tmp("backwards");
  testing::copyDataset(mixedDataset(), tmp / "d");
  // Frames 0..14 at k/30 s, then frame 15 goes back to 5/30 s and the clock runs on from there.
  testing::writeTimestamps(tmp / "d", kFrames, [](int k) { return (k < 15 ? k : k - 10) / 30.0; });
  for (const bool realtime : {true, false}) {
    SCOPED_TRACE(realtime ? "realtime" : "as fast as possible");
    const fs::path lcm_log = tmp / (realtime ? "rt.lcm" : "fast.lcm");
    const auto t0 = std::chrono::steady_clock::now();
    const DaemonRun r = runDaemon(tmp, testing::fileSourceConfig(tmp / "d", logUrl(lcm_log), realtime),
                                  lcm_log);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ASSERT_EQ(r.exit_code, 0) << r.err;
    EXPECT_THAT(r.err, HasSubstr("time went backwards"));
    const auto& log = r.log;
    ASSERT_FALSE(log.statuses.empty());
    const status_t& last = log.statuses.back();
    EXPECT_TRUE(last.final);
    if (realtime) {
      // Paced again from the backwards frame: nothing is treated as late and dropped; the
      // run lasts the recording's 25 frame intervals (not 15 + 20), and the machine may lag.
      EXPECT_EQ(last.frames_received, kFrames);
      EXPECT_LT(last.frames_lost_upstream, 5) << "frames after the backwards step were dropped as late";
      EXPECT_GT(seconds, 24 / 30.0);
    } else {
      EXPECT_EQ(last.frames_received, kFrames);
      EXPECT_EQ(last.frames_processed, kFrames);
    }
    // The last fault, unless a slow machine (sanitizers) dropped stale frames in realtime: a
    // frame across them may then be beyond a window's reach and not believed, a later fault.
    if (!realtime || last.frames_skipped_stale == 0) {
      EXPECT_THAT(last.last_error, HasSubstr("time went backwards"));
    }
    bool saw_15 = false;
    for (std::size_t k = 1; k < log.poses.size(); ++k) {
      const pose_t& p = log.poses[k];
      EXPECT_GT(p.utime, log.poses[k - 1].utime) << "pose times never go backwards";
      // A backwards time step is a gap: the next frame is found again against the keyframe.
      // In realtime on a slow machine (sanitizers) stale frames are dropped, and a gap whose
      // motion cannot be found starts exactly one new segment instead.
      const pose_t& before = log.poses[k - 1];
      if (p.status == pose_t::STATUS_LOST) {
        EXPECT_TRUE(realtime && last.frames_skipped_stale > 0) << "frame " << p.source_index;
        EXPECT_EQ(p.segment, before.segment + 1);
        EXPECT_EQ(p.track_state, pose_t::TRACK_LOST);
      } else {
        EXPECT_EQ(p.segment, before.segment);
      }
      EXPECT_LE(p.segment, realtime ? 3 : 0);
      if (p.source_index == 15 && p.status != pose_t::STATUS_LOST) {
        saw_15 = true;
        EXPECT_EQ(p.track_state, pose_t::TRACK_BRIDGED);
        EXPECT_EQ(p.reference_sequence, log.poses[k - 1].sequence);
      }
    }
    EXPECT_TRUE(saw_15 || last.frames_skipped_stale > 0);
  }
}

/// Why a test that needs a mount namespace is skipped (after unshareMountCommand failed).
std::string noMountNamespace(const TempDir& tmp) {
  return "mount namespaces are not allowed here (unshare -rm / -m failed: " +
         testing::readText(tmp / "u.err") + ")";
}

/// "unshare -rm" (or "-m" as root) when this system allows mount namespaces.
std::vector<std::string> unshareMountCommand(const TempDir& tmp) {
  for (const char* flags : {"-rm", "-m"}) {
    if (testing::runProcess({"/usr/bin/unshare", flags, "/bin/sh", "-c",
                             "mount -t tmpfs -o size=64k tmpfs '" + tmp.path().string() + "'"},
                            tmp / "u.out", tmp / "u.err", 10s) == 0)
      return {"/usr/bin/unshare", flags};
  }
  return {};
}

TEST(OmniposedFaults, LogDiskFullMidRunIsReportedPipelineKeepsGoingAndLogRecovers) {
  TempDir tmp("diskfull");
  TempDir mnt("diskfull-mnt");
  const auto unshare = unshareMountCommand(mnt);
  if (unshare.empty()) GTEST_SKIP() << noMountNamespace(mnt);
  const fs::path small = mnt.path();  // a 2 MiB tmpfs inside the namespace
  const fs::path lcm_log = small / "run.lcm";
  testing::writeText(tmp / "daemon.yaml",
                     testing::fileSourceConfig(mixedDataset(), logUrl(lcm_log), /*realtime=*/false,
                                               /*loop=*/true, "  status_hz: 10\n"));
  // In the namespace: a 2 MiB tmpfs with a filler that leaves 48 KiB; the daemon fills
  // those, then the test removes the filler and stops the daemon 1.5 s later; the log is
  // copied out. The space that comes back (2000 KiB) must be far more than the daemon can
  // fill in those 1.5 s (at ~100 frames/s, ~25 KiB/s of poses and statuses), or its final
  // status finds the disk full again (a 48 KiB filler did, once the pipeline got faster).
  const std::string script =
      "set -e; mount -t tmpfs -o size=2048k tmpfs '" + small.string() + "'\n"
      "head -c 2048000 /dev/zero > '" + (small / "filler").string() + "'; set +e\n"
      "'" + omniposed().string() + "' --config '" + (tmp / "daemon.yaml").string() + "' 2> '" +
      (tmp / "err").string() + "' & D=$!\n"
      "echo $D > '" + (tmp / "pid").string() + "'\n"
      "while [ ! -e '" + (tmp / "release").string() + "' ]; do sleep 0.05; done\n"
      "rm '" + (small / "filler").string() + "'\n"
      "touch '" + (tmp / "released").string() + "'\n"
      "wait $D; rc=$?\n"
      "cp '" + lcm_log.string() + "' '" + (tmp / "run.lcm").string() + "'\n"
      "exit $rc\n";
  std::vector<std::string> argv = unshare;
  argv.insert(argv.end(), {"/bin/sh", "-c", script});
  testing::Child ns(argv, tmp / "ns.out", tmp / "ns.err");
  auto waitForText = [&](const fs::path& file, const std::string& needle, std::chrono::seconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    while (testing::readText(file).find(needle) == std::string::npos) {
      if (std::chrono::steady_clock::now() > deadline) return false;
      std::this_thread::sleep_for(50ms);
    }
    return true;
  };
  ASSERT_TRUE(waitForText(tmp / "err", "No space left on device", 120s))
      << testing::readText(tmp / "err") << testing::readText(tmp / "ns.err");
  const std::string full = testing::readText(tmp / "err");
  EXPECT_THAT(full, HasSubstr(lcm_log.string())) << "the fault names the log:\n" << full;
  ASSERT_TRUE(waitForText(tmp / "pid", "\n", 10s));
  const pid_t daemon_pid = std::stoi(testing::readText(tmp / "pid"));
  // The pipeline keeps going while nothing can be written: ask for the counters twice.
  std::this_thread::sleep_for(1500ms);
  ::kill(daemon_pid, SIGHUP);
  ASSERT_TRUE(waitForText(tmp / "err", "SIGHUP received", 10s)) << testing::readText(tmp / "err");
  // Space comes back; the daemon writes whole records again.
  testing::writeText(tmp / "release", "");
  ASSERT_TRUE(waitForText(tmp / "released", "", 10s));
  std::this_thread::sleep_for(1500ms);
  ::kill(daemon_pid, SIGTERM);
  const int rc = ns.wait(30s);
  const std::string err = testing::readText(tmp / "err");
  ASSERT_EQ(rc, 0) << "no crash, clean stop:\n" << err << testing::readText(tmp / "ns.err");
  EXPECT_THAT(err, HasSubstr("stopped:"));
  // The counters logged at the end: frames went on being processed while the log was full.
  const auto at = err.rfind("stopped:");
  ASSERT_NE(at, std::string::npos);
  long long received = 0, processed = 0, skipped = 0, bad = 0, publish_failures = 0;
  ASSERT_EQ(std::sscanf(err.c_str() + at, "stopped: received %lld, processed %lld, skipped (stale) %lld, bad %lld",
                        &received, &processed, &skipped, &bad),
            4)
      << err.substr(at);
  const auto pf = err.find("publish failures ", at);
  ASSERT_NE(pf, std::string::npos);
  publish_failures = std::atoll(err.c_str() + pf + std::strlen("publish failures "));
  EXPECT_GT(publish_failures, 0);
  // The log is whole records only, and it goes on after the disk-full stretch.
  const auto log = testing::readLcmLog(tmp / "run.lcm");
  EXPECT_EQ(log.undecodable, 0);
  ASSERT_FALSE(log.poses.empty());
  ASSERT_FALSE(log.statuses.empty());
  const status_t& last = log.statuses.back();
  EXPECT_TRUE(last.final) << "the final status was written after space came back";
  EXPECT_EQ(last.frames_processed, processed);
  EXPECT_LT(static_cast<long long>(log.poses.size()), processed) << "poses lost while full";
  EXPECT_THAT(last.last_error, HasSubstr("No space left on device"));
  EXPECT_THAT(last.last_error, HasSubstr(lcm_log.string()));
  // Sequence numbers jump over the poses that could not be written, and resume after.
  bool jumped = false;
  for (std::size_t k = 1; k < log.poses.size(); ++k)
    jumped |= log.poses[k].sequence > log.poses[k - 1].sequence + 1;
  EXPECT_TRUE(jumped);
}


// ---------------------------------------------------------------------------------------
// Start-up: nothing blocks, nothing runs away, a stop is obeyed, one writer per log
// ---------------------------------------------------------------------------------------

/// Waits until `file` holds `needle` (false after `timeout`).
bool waitForText(const fs::path& file, const std::string& needle, std::chrono::milliseconds timeout) {
  const auto deadline = std::chrono::steady_clock::now() + timeout;
  while (testing::readText(file).find(needle) == std::string::npos) {
    if (std::chrono::steady_clock::now() > deadline) return false;
    std::this_thread::sleep_for(20ms);
  }
  return true;
}

TEST(OmniposedFaults, InputsThatWouldBlockOrRunAwayAreRefusedAtOnceByName) {
  TempDir tmp("blocking-inputs");
  ASSERT_EQ(::mkfifo((tmp / "fifo").c_str(), 0600), 0);
  fs::create_directory(tmp / "config_dir");
  testing::copyDataset(mixedDataset(), tmp / "fifo_stamps");
  fs::remove(tmp / "fifo_stamps/timestamps.txt");
  ASSERT_EQ(::mkfifo((tmp / "fifo_stamps/timestamps.txt").c_str(), 0600), 0);
  testing::copyDataset(mixedDataset(), tmp / "zero_truth");
  fs::remove(tmp / "zero_truth/groundtruth.tum");
  fs::create_symlink("/dev/zero", tmp / "zero_truth/groundtruth.tum");
  const std::string calibration_text = testing::readText(mixedDataset() / "calibration.yaml");
  testing::writeText(tmp / "calibration_copy.yaml", calibration_text);
  struct Case {
    std::string name;
    std::string config;  ///< "" = the configuration path is the directory config_dir
    std::string says;
  };
  const std::string log = logUrl(tmp / "run.lcm");
  const auto withPipeline = [&](const std::string& pipeline) {
    return testing::fileSourceConfig(mixedDataset(), log, false) + "pipeline: {" + pipeline + "}\n";
  };
  const std::vector<Case> cases = {
      {"timestamps.txt a FIFO", testing::fileSourceConfig(tmp / "fifo_stamps", log, false),
       "timestamps.txt: not a regular file (a FIFO)"},
      {"groundtruth.tum /dev/zero", testing::fileSourceConfig(tmp / "zero_truth", log, false),
       "groundtruth.tum: not a regular file (a character device)"},
      {"the log a FIFO without a reader", testing::fileSourceConfig(mixedDataset(), logUrl(tmp / "fifo"), false),
       (tmp / "fifo").string() + ": not a regular file (a FIFO)"},
      {"the wisdom a FIFO", withPipeline("fftw_wisdom: " + (tmp / "fifo").string()),
       "pipeline.fftw_wisdom: " + (tmp / "fifo").string() + ": not a regular file (a FIFO)"},
      {"the wisdom /dev/zero", withPipeline("fftw_wisdom: /dev/zero"),
       "pipeline.fftw_wisdom: /dev/zero: not a regular file (a character device)"},
      {"the wisdom a calibration", withPipeline("fftw_wisdom: " + (tmp / "calibration_copy.yaml").string()),
       "calibration_copy.yaml: exists and is not an FFTW wisdom file; not replaced"},
      {"the configuration a directory", "", "config_dir: not a regular file (a directory)"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    const fs::path config = c.config.empty() ? tmp / "config_dir" : tmp / "daemon.yaml";
    if (!c.config.empty()) testing::writeText(config, c.config);
    for (const bool check : {false, true}) {
      std::vector<std::string> argv = {omniposed().string(), "--config", config.string()};
      if (check) argv.push_back("--check");
      const auto start = std::chrono::steady_clock::now();
      const int rc = testing::runProcess(argv, tmp / "out.txt", tmp / "err.txt", 20s);
      const auto took = std::chrono::steady_clock::now() - start;
      const std::string err = testing::readText(tmp / "err.txt");
      EXPECT_EQ(rc, 1) << (check ? "--check\n" : "") << err;
      EXPECT_LT(took, 5s) << "refused at once, not after reading or waiting";
      EXPECT_THAT(err, HasSubstr(c.says)) << (check ? "--check\n" : "") << err;
    }
  }
  EXPECT_EQ(testing::readText(tmp / "calibration_copy.yaml"), calibration_text) << "never overwritten";
  EXPECT_TRUE(fs::is_fifo(tmp / "fifo"));
}

TEST(OmniposedFaults, CheckWritesNothing) {
  TempDir tmp("check-writes-nothing");
  const fs::path wisdom = tmp / "wisdom.txt";
  const fs::path lcm_log = tmp / "run.lcm";
  testing::writeText(tmp / "daemon.yaml", testing::fileSourceConfig(mixedDataset(), logUrl(lcm_log), false) +
                                              "pipeline: {fftw_wisdom: " + wisdom.string() + "}\n");
  const int rc = testing::runProcess({omniposed().string(), "--config", (tmp / "daemon.yaml").string(), "--check"},
                                     tmp / "out.txt", tmp / "err.txt", 60s);
  const std::string err = testing::readText(tmp / "err.txt");
  EXPECT_EQ(rc, 0) << err;
  EXPECT_THAT(err, HasSubstr("fftw_wisdom " + wisdom.string() + ": absent"));
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(tmp.path())) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  EXPECT_EQ(names, (std::vector<std::string>{"daemon.yaml", "err.txt", "out.txt"}))
      << "no wisdom, log or lock file";
}

TEST(OmniposedFaults, SigtermDuringStartUpEndsTheProcessWithinASecond) {
  // A start-up that takes seconds: FFTW plans 512 x 512 windows patiently (a wisdom file is
  // given and empty) for a 3000 x 520 panorama.
  TempDir tmp("startup-sigterm");
  std::string calibration = testing::readText(mixedDataset() / "calibration.yaml");
  const auto replace = [&](const std::string& from, const std::string& to) {
    const auto at = calibration.find(from);
    ASSERT_NE(at, std::string::npos) << from;
    calibration.replace(at, from.size(), to);
  };
  replace("width: 1100", "width: 3000");
  replace("height: 110", "height: 520");
  replace("horizon_row: 54.5", "horizon_row: 259.5");
  testing::writeText(tmp / "calibration.yaml", calibration);
  testing::writeText(tmp / "daemon.yaml",
                     "source: {type: file, path: " + mixedDataset().string() + ", realtime: false}\n"
                     "calibration: " + (tmp / "calibration.yaml").string() + "\n"
                     "pipeline: {window: 512, step: 64, fftw_wisdom: " + (tmp / "wisdom.txt").string() + "}\n"
                     "lcm: {url: '" + logUrl(tmp / "run.lcm") + "'}\n");
  testing::Child daemon({omniposed().string(), "--config", (tmp / "daemon.yaml").string()}, tmp / "out.txt",
                        tmp / "err.txt");
  ASSERT_TRUE(waitForText(tmp / "err.txt", "(effective values)", 20s)) << testing::readText(tmp / "err.txt");
  std::this_thread::sleep_for(300ms);  // into the FFT planning
  ASSERT_FALSE(waitForText(tmp / "err.txt", "omniposed: source:", 0ms))
      << "start-up finished within 300 ms: this machine plans too fast for the test";
  const auto sent = std::chrono::steady_clock::now();
  daemon.signal(SIGTERM);
  const int rc = daemon.wait(5s);
  const auto took = std::chrono::steady_clock::now() - sent;
  const std::string err = testing::readText(tmp / "err.txt");
  EXPECT_EQ(rc, 0) << err;
  EXPECT_LT(took, 1s) << err;
  EXPECT_THAT(err,
              HasSubstr("omniposed: SIGTERM received during start-up (building the pipeline "
                        "(FFT plans)): stopping"));
}

TEST(OmniposedFaults, ASecondDaemonOnTheSameLogIsRefusedWithTheHoldersPid) {
  TempDir tmp("two-daemons");
  const fs::path lcm_log = tmp / "run.lcm";
  testing::writeText(tmp / "daemon.yaml",
                     testing::fileSourceConfig(mixedDataset(), logUrl(lcm_log), /*realtime=*/true, /*loop=*/true));
  testing::Child first({omniposed().string(), "--config", (tmp / "daemon.yaml").string()}, tmp / "out1.txt",
                       tmp / "err1.txt");
  ASSERT_TRUE(waitForText(tmp / "err1.txt", "omniposed: source:", 60s)) << testing::readText(tmp / "err1.txt");
  const int rc = testing::runProcess({omniposed().string(), "--config", (tmp / "daemon.yaml").string()},
                                     tmp / "out2.txt", tmp / "err2.txt", 30s);
  const std::string err = testing::readText(tmp / "err2.txt");
  EXPECT_EQ(rc, 1) << err;
  EXPECT_THAT(err,
              HasSubstr("the log is in use by another omniposed: " + lcm_log.string() +
                        ".lock: held by process " + std::to_string(first.pid())));
  std::this_thread::sleep_for(500ms);
  first.signal(SIGTERM);
  ASSERT_EQ(first.wait(30s), 0) << testing::readText(tmp / "err1.txt");
  const auto log = testing::readLcmLog(lcm_log);
  EXPECT_EQ(log.undecodable, 0);
  EXPECT_FALSE(log.poses.empty()) << "the first daemon's log is whole";
  ASSERT_FALSE(log.statuses.empty());
  EXPECT_TRUE(log.statuses.back().final);
  // The lock goes with its holder: a third daemon starts.
  testing::writeText(tmp / "daemon.yaml", testing::fileSourceConfig(mixedDataset(), logUrl(lcm_log), false));
  EXPECT_EQ(testing::runProcess({omniposed().string(), "--config", (tmp / "daemon.yaml").string()},
                                tmp / "out3.txt", tmp / "err3.txt", 60s),
            0)
      << testing::readText(tmp / "err3.txt");
}

TEST(OmniposedFaults, ARunInWhichEveryPublishFailedExitsNonZero) {
  TempDir tmp("nothing-published");
  TempDir mnt("nothing-published-mnt");
  const auto unshare = unshareMountCommand(mnt);
  if (unshare.empty()) GTEST_SKIP() << noMountNamespace(mnt);
  const fs::path lcm_log = mnt.path() / "run.lcm";
  testing::writeText(tmp / "daemon.yaml", testing::fileSourceConfig(mixedDataset(), logUrl(lcm_log), false));
  // A full 64 KiB tmpfs: the log is created (an inode is left), no byte of it is written.
  const std::string script =
      "set -e; mount -t tmpfs -o size=64k tmpfs '" + mnt.path().string() + "'\n"
      "cat /dev/zero > '" + (mnt / "filler").string() + "' 2>/dev/null || true\n"
      "exec '" + omniposed().string() + "' --config '" + (tmp / "daemon.yaml").string() + "'\n";
  std::vector<std::string> argv = unshare;
  argv.insert(argv.end(), {"/bin/sh", "-c", script});
  const int rc = testing::runProcess(argv, tmp / "out.txt", tmp / "err.txt", 120s);
  const std::string err = testing::readText(tmp / "err.txt");
  EXPECT_EQ(rc, 3) << err;
  EXPECT_THAT(err, HasSubstr("every message failed to publish"));
  EXPECT_THAT(err, HasSubstr("No space left on device"));
}

}  // namespace
}  // namespace omnipose
