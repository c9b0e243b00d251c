// The per-frame path of the daemon allocates nothing after start-up (DESIGN.md section 5).
//
// This binary links tests/support/allocation_counter.hpp, which replaces operator new/delete
// (every variant) and, by symbol interposition, malloc/calloc/realloc/memalign/
// posix_memalign/aligned_alloc/valloc/pvalloc, so allocations inside C libraries (OpenCV's
// fastMalloc, FFTW, LCM's C core, glib) are counted as well as C++ ones, in every thread of
// the process.
//
// What runs while counting (all threads of the whole daemon, >= 120 processed frames after
// warm-up): the capture thread pulling frames from an in-memory source (preloaded omni
// frames, copied into the mailbox slot: PNG decoding of the file source is NOT part of the
// measurement) at 500 Hz, i.e. faster than the pipeline, so stale frames are skipped;
// scripted bad frames and a source disconnect + re-open (the gap paths); the processor
// (unwrap, iFMI registration, fit, refinement, pose chain, pose/diagnostics/status
// encoding); status at 20 Hz; fit diagnostics on.
//
// Test 1 (file:// LCM log): allocations inside the sink's publish call are counted
// separately (the log writer), and both must be 0. Test 2 (udpm://, inside a private
// network namespace of a forked child): nothing is excluded, the whole process must make
// 0 allocations, LCM's publish included.
#include <gtest/gtest.h>
#include <net/if.h>
#include <net/route.h>
#include <netinet/in.h>
#include <sched.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include <atomic>
#include <cstring>
#include <new>

#include "allocation_counter.hpp"
#include "daemon/daemon.hpp"
#include "daemon/map_keeper.hpp"
#include "daemon_test_support.hpp"

namespace omnipose {
namespace {

using namespace std::chrono_literals;
namespace fs = std::filesystem;
using daemon::Daemon;
using testing::AllocationCounter;

constexpr long kWarmUpFrames = 20;
constexpr long kCountedFrames = 120;

/// Attributes allocations made inside the LCM publish call to LCM.
class AttributingSink final : public daemon::MessageSink {
 public:
  explicit AttributingSink(std::unique_ptr<daemon::MessageSink> inner) : inner_(std::move(inner)) {}
  bool publish(const std::string& channel, const std::uint8_t* data, std::size_t size) override {
    if (counting_.load(std::memory_order_relaxed)) publishes_.fetch_add(1);
    AllocationCounter::ExcludedScope in_lcm;  // counted apart: AllocationCounter::excluded()
    return inner_->publish(channel, data, size);
  }
  void setCounting(bool on) { counting_ = on; }
  std::string describe() const override { return inner_->describe(); }
  long publishes() const { return publishes_.load(); }

 private:
  std::unique_ptr<daemon::MessageSink> inner_;
  std::atomic<long> publishes_{0};
  std::atomic<bool> counting_{false};
};

struct Measurement {
  long own = 0;
  long lcm = 0;
  long processed = 0;
  long skipped = 0;
  long bad = 0;
  long failures = 0;
  long publishes = 0;
  bool ok = false;
};

/// Runs the whole daemon on an endless in-memory source and counts allocations over
/// kCountedFrames processed frames after kWarmUpFrames of warm-up.
Measurement measure(const std::vector<cv::Mat>& frames, const std::string& lcm_url,
                    const std::string& calibration, std::FILE* log) {
  const DaemonConfig config = DaemonConfig::parse(
      "source: {type: file, path: /unused}\ncalibration: " + calibration +
          "\npipeline: {threads: 2}"  // the worker pool runs (and must not allocate) too
          "\nlcm: {url: '" + lcm_url + "', fit_channel: OMNI_FIT, status_hz: 20}\n",
      "alloc-test.yaml", "/");
  testing::MemorySource::Script script;
  // 500 Hz: faster than the pipeline on any machine, so stale frames are skipped (at 100 Hz
  // a 2-core x86 VM kept up from 2026-11 on, and the skip and re-open paths no longer ran
  // while counting).
  script.period = 2ms;
  for (long n = 5; n < 1000000; n += 37) script.bad.insert(n);          // corrupt frames
  for (long n = 13; n < 1000000; n += 151) script.disconnect.insert(n);  // unplugged, re-opened
  auto sink = std::make_unique<AttributingSink>(daemon::makeLcmSink(lcm_url));
  AttributingSink* sink_ptr = sink.get();
  Daemon::Options options;
  options.capture.reconnect_initial = 5ms;
  Daemon d(config, log, std::make_unique<testing::MemorySource>(frames, script), std::move(sink),
           options);

  Measurement m;
  d.start();
  const auto deadline = std::chrono::steady_clock::now() + 120s;
  auto processed = [&] { return d.stats().frames_processed; };
  while (processed() < kWarmUpFrames && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(5ms);
  const daemon::DaemonStats before = d.stats();
  {
    // Every thread of the process; who allocated is recorded for the report.
    AllocationCounter counter(AllocationCounter::Scope::kProcess, /*record_callers=*/true);
    sink_ptr->setCounting(true);
    while (processed() < before.frames_processed + kCountedFrames &&
           std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(5ms);
    sink_ptr->setCounting(false);
    m.own = counter.stop();
    m.lcm = counter.excluded();
    if (m.own != 0) counter.printCallers(stderr);
  }
  const daemon::DaemonStats after = d.stats();
  d.requestStop();
  d.join();

  m.processed = after.frames_processed - before.frames_processed;
  m.skipped = after.frames_skipped_stale - before.frames_skipped_stale;
  m.bad = after.frames_bad - before.frames_bad;
  m.failures = after.source_failures - before.source_failures;
  m.publishes = sink_ptr->publishes();
  m.ok = m.processed >= kCountedFrames;
  return m;
}

std::string calibrationPath(const testing::TempDir& tmp) {
  const fs::path path = tmp / "calibration.yaml";
  Calibration{}.save(path);
  return path.string();
}

TEST(DaemonAllocation, PerFramePathAllocatesNothingLcmFileLogAttributedSeparately) {
  if (!AllocationCounter::available())
    GTEST_SKIP() << "sanitizer build: the sanitizer owns malloc, allocations are not counted";
  testing::TempDir tmp("alloc");
  const auto frames = testing::renderFrames("mixed", 8);
  std::FILE* log = std::tmpfile();
  const Measurement m =
      measure(frames, "file://" + (tmp / "alloc.lcm").string() + "?mode=w", calibrationPath(tmp), log);
  std::fclose(log);
  ASSERT_TRUE(m.ok) << "only " << m.processed << " frames processed in time";
  // own: allocations outside the LCM publish call (daemon, pipeline and the libraries they
  // call); lcm: inside the sink's publish (file:// log).
  RecordProperty("frames_processed", static_cast<int>(m.processed));
  RecordProperty("frames_skipped_stale", static_cast<int>(m.skipped));
  RecordProperty("frames_bad", static_cast<int>(m.bad));
  RecordProperty("source_reopens", static_cast<int>(m.failures));
  RecordProperty("own_allocations", static_cast<int>(m.own));
  RecordProperty("lcm_file_allocations", static_cast<int>(m.lcm));
  RecordProperty("publishes", static_cast<int>(m.publishes));
  EXPECT_EQ(m.own, 0) << "heap allocations on the per-frame path (backtraces above)";
  // The fault and skip paths really ran while counting.
  EXPECT_GT(m.skipped, 0);
  EXPECT_GT(m.bad, 0);
  EXPECT_GT(m.failures, 0);
  // The file:// log is written by the daemon's own sink (LCM's eventlog writer, from the
  // encoded buffer): unlike LCM 1.3.1's file provider (one malloc per message) it allocates
  // nothing either.
  EXPECT_EQ(m.lcm, 0);
}

/// Puts the calling process into a new network namespace with only the loopback interface
/// up and the multicast route on it (like `unshare -rn` + `ip link set lo up` + `ip route
/// add 224.0.0.0/4 dev lo`). Returns an error text, empty on success.
std::string enterPrivateNetwork() {
  const uid_t uid = geteuid();
  const gid_t gid = getegid();
  if (uid == 0) {
    if (unshare(CLONE_NEWNET) != 0) return std::string("unshare(CLONE_NEWNET): ") + std::strerror(errno);
  } else {
    if (unshare(CLONE_NEWUSER | CLONE_NEWNET) != 0)
      return std::string("unshare(CLONE_NEWUSER|CLONE_NEWNET): ") + std::strerror(errno);
    testing::writeText("/proc/self/setgroups", "deny");
    testing::writeText("/proc/self/uid_map", "0 " + std::to_string(uid) + " 1");
    testing::writeText("/proc/self/gid_map", "0 " + std::to_string(gid) + " 1");
  }
  const int s = socket(AF_INET, SOCK_DGRAM, 0);
  if (s < 0) return "socket failed";
  ifreq ifr{};
  std::strncpy(ifr.ifr_name, "lo", IFNAMSIZ - 1);
  if (ioctl(s, SIOCGIFFLAGS, &ifr) != 0) return "SIOCGIFFLAGS lo failed";
  ifr.ifr_flags |= IFF_UP | IFF_RUNNING;
  if (ioctl(s, SIOCSIFFLAGS, &ifr) != 0) return std::string("lo up: ") + std::strerror(errno);
  rtentry route{};
  auto* dst = reinterpret_cast<sockaddr_in*>(&route.rt_dst);
  dst->sin_family = AF_INET;
  dst->sin_addr.s_addr = htonl(0xE0000000u);  // 224.0.0.0
  auto* mask = reinterpret_cast<sockaddr_in*>(&route.rt_genmask);
  mask->sin_family = AF_INET;
  mask->sin_addr.s_addr = htonl(0xF0000000u);  // /4
  route.rt_flags = RTF_UP;
  char dev[] = "lo";
  route.rt_dev = dev;
  if (ioctl(s, SIOCADDRT, &route) != 0) return std::string("multicast route: ") + std::strerror(errno);
  close(s);
  return {};
}

TEST(DaemonAllocation, WholeProcessIncludingLcmUdpmPublishAllocatesNothing) {
  if (!AllocationCounter::available())
    GTEST_SKIP() << "sanitizer build: the sanitizer owns malloc, allocations are not counted";
  testing::TempDir tmp("alloc-udpm");
  const auto frames = testing::renderFrames("mixed", 8);
  const std::string calibration = calibrationPath(tmp);
  int fds[2];
  ASSERT_EQ(pipe(fds), 0);
  const pid_t pid = fork();
  ASSERT_GE(pid, 0);
  if (pid == 0) {
    // Child: private network, whole daemon over udpm (multicast never leaves it).
    close(fds[0]);
    char line[256];
    const std::string error = enterPrivateNetwork();
    if (!error.empty()) {
      std::snprintf(line, sizeof(line), "skip %s", error.c_str());
    } else {
      std::FILE* log = std::tmpfile();
      const Measurement m = measure(frames, "udpm://239.255.76.67:7667?ttl=0", calibration, log);
      std::snprintf(line, sizeof(line), "ok %d %ld %ld %ld %ld %ld %ld", m.ok ? 1 : 0, m.own,
                    m.lcm, m.processed, m.skipped, m.bad, m.publishes);
    }
    [[maybe_unused]] auto written = write(fds[1], line, std::strlen(line));
    _exit(0);
  }
  close(fds[1]);
  std::string result;
  char buf[256];
  ssize_t n;
  while ((n = read(fds[0], buf, sizeof(buf))) > 0) result.append(buf, static_cast<std::size_t>(n));
  close(fds[0]);
  int status = 0;
  waitpid(pid, &status, 0);
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << "child failed: " << result;
  if (result.rfind("skip ", 0) == 0) {
    GTEST_SKIP() << "no private network namespace here (" << result.substr(5)
                 << "); udpm is never used outside one";
  }
  int ok = 0;
  long own = -1, lcm = -1, processed = 0, skipped = 0, bad = 0, publishes = 0;
  ASSERT_EQ(std::sscanf(result.c_str(), "ok %d %ld %ld %ld %ld %ld %ld", &ok, &own, &lcm,
                        &processed, &skipped, &bad, &publishes),
            7)
      << result;
  ASSERT_EQ(ok, 1) << "only " << processed << " frames processed in time";
  RecordProperty("frames_processed", static_cast<int>(processed));
  RecordProperty("frames_skipped_stale", static_cast<int>(skipped));
  RecordProperty("frames_bad", static_cast<int>(bad));
  RecordProperty("publishes", static_cast<int>(publishes));
  RecordProperty("own_allocations", static_cast<int>(own));
  RecordProperty("lcm_udpm_allocations", static_cast<int>(lcm));
  EXPECT_EQ(own, 0) << "allocations outside the LCM publish call";
  EXPECT_EQ(lcm, 0) << "LCM's udpm publish allocated";
}

TEST(DaemonAllocation, TheMapsSnapshotOnTheFrameThreadAllocatesNothing) {
  if (!AllocationCounter::available())
    GTEST_SKIP() << "sanitizer build: the sanitizer owns malloc, allocations are not counted";
  // The frame thread's part of keeping the map (MapKeeper::afterFrame(): a copy of the map
  // handed to the saver thread every save_interval_s); the saver's writing is not realtime
  // and is not counted (this thread only).
  testing::TempDir tmp("map-keeper-alloc");
  const std::vector<cv::Mat> frames = testing::renderFrames("translate", 12);
  OdometryOptions options;
  options.pipeline.threads = 1;
  Odometry odometry(Calibration{}, options);
  daemon::StatusBoard board(nullptr);
  MapFileConfig config;
  config.path = tmp / "robot.map";
  config.save_interval_s = 1e-6;  // every frame the saver is idle
  daemon::MapKeeper keeper(config, options.loop_closure.max_places, board);
  keeper.load(odometry, Calibration{});
  for (std::size_t k = 0; k < 4; ++k) ASSERT_TRUE(odometry.process(frames[k], {k / 30.0}));
  long allocations = 0;
  for (std::size_t k = 4; k < frames.size(); ++k) {
    const auto result = odometry.process(frames[k], {k / 30.0});
    ASSERT_TRUE(result);
    AllocationCounter mine(AllocationCounter::Scope::kThisThread);
    keeper.afterFrame(odometry, *result, k, daemon::SteadyClock::now());
    allocations += mine.stop();
    // Give the saver its time: the next frame then snapshots again.
    for (int wait = 0; wait < 200 && board.maps_saved.load() < static_cast<long>(k - 3); ++wait)
      std::this_thread::sleep_for(5ms);
  }
  RecordProperty("maps_saved", static_cast<int>(board.maps_saved.load()));
  EXPECT_GE(board.maps_saved.load(), 4) << "snapshots were taken and written";
  EXPECT_EQ(board.map_save_failures.load(), 0);
  EXPECT_EQ(allocations, 0);
}

}  // namespace
}  // namespace omnipose
