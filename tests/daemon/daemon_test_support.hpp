#pragma once
// Shared helpers of the daemon tests: rendered datasets (exact renderer), temporary
// directories, an in-memory frame source with scripted faults, LCM log decoding, ground-truth
// comparison and child processes.

#include <fcntl.h>
#include <spawn.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <lcm/lcm-cpp.hpp>

#include <Eigen/Geometry>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <opencv2/core.hpp>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "daemon/message_sink.hpp"
#include "omnipose/calibration.hpp"
#include "omnipose/fit_diagnostics_t.hpp"
#include "omnipose/gyro.hpp"
#include "omnipose/imu_t.hpp"
#include "omnipose/panorama_image_t.hpp"
#include "omnipose/frame_source.hpp"
#include "omnipose/io/trajectory.hpp"
#include "omnipose/pose_t.hpp"
#include "omnipose/status_t.hpp"
#include "omnipose/synth/synth.hpp"
#include "shared_lcm_sink.hpp"
#include "test_files.hpp"

extern char** environ;

namespace omnipose::testing {

namespace fs = std::filesystem;

/// The bundled indoor photo (tests/data/equirect, MIT-licensed).
inline fs::path indoorPhoto() {
  return fs::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg";
}
inline fs::path binaryDir() { return fs::path(OMNIPOSE_BINARY_DIR) / "bin"; }


/// A rendered dataset shared by all test processes (ctest runs each test in its own
/// process): OMNIPOSE_BINARY_DIR/tests/daemon-data/<name>-<stamp>, where the stamp is the
/// modification time of this test binary (and of `also_depends_on`, if given), so any
/// rebuild renders afresh. `render(dir)` writes the dataset; it runs into a private
/// temporary directory that is renamed into place, so concurrent tests never see half a
/// dataset. Older versions of the same name are removed.
inline fs::path cachedDataset(const std::string& name,
                              const std::function<void(const fs::path&)>& render,
                              const fs::path& also_depends_on = {}) {
  const fs::path root = fs::path(OMNIPOSE_BINARY_DIR) / "tests" / "daemon-data";
  fs::create_directories(root);
  auto stamp = [](const fs::path& p) {
    return std::to_string(fs::last_write_time(p).time_since_epoch().count());
  };
  std::string key = name + "-" + stamp("/proc/self/exe");
  if (!also_depends_on.empty()) key += "-" + stamp(also_depends_on);
  const fs::path dir = root / key;
  if (fs::is_directory(dir)) return dir;
  std::error_code ec;
  for (const auto& entry : fs::directory_iterator(root)) {
    const std::string other = entry.path().filename().string();
    if (other.rfind(name + "-", 0) == 0 && other.find(".tmp.") == std::string::npos)
      fs::remove_all(entry.path(), ec);
  }
  const fs::path tmp = root / (key + ".tmp." + std::to_string(getpid()));
  fs::remove_all(tmp, ec);
  render(tmp);
  fs::rename(tmp, dir, ec);
  if (ec) fs::remove_all(tmp, ec);  // another process was first: use its copy
  if (!fs::is_directory(dir)) throw std::runtime_error("cannot create " + dir.string());
  return dir;
}

/// Renders `frames` frames of a motion preset into a dataset directory (DESIGN.md section 6)
/// with the exact renderer (sphere scene: pure rotation is exact), PNG, no noise.
inline void renderDataset(const fs::path& dir, const std::string& preset, int frames,
                          int supersample = 1, std::uint64_t seed = 3) {
  synth::MotionScript script = synth::MotionScript::preset(preset);
  script.frames = frames;
  script.seed = seed;
  const synth::Scene scene = synth::Scene::load(indoorPhoto(), synth::SceneKind::kSphere);
  const synth::Renderer renderer(scene, Calibration{}, {synth::OutputKind::kOmni, supersample});
  const auto poses = synth::generateTrajectory(script);
  synth::DatasetWriter writer(dir, Calibration{}, 0);
  for (std::size_t k = 0; k < poses.size(); ++k)
    writer.addFrame(synth::degrade(renderer.render(poses[k].pose), {}, k), poses[k]);
  writer.finish();
}

/// Renders `count` grey frames (CV_8UC1) of a preset in memory.
inline std::vector<cv::Mat> renderFrames(const std::string& preset, int count,
                                         int supersample = 1, std::uint64_t seed = 3) {
  synth::MotionScript script = synth::MotionScript::preset(preset);
  script.frames = count;
  script.seed = seed;
  const synth::Renderer renderer(synth::Scene::load(indoorPhoto(), synth::SceneKind::kSphere),
                                 Calibration{}, {synth::OutputKind::kOmni, supersample});
  std::vector<cv::Mat> out;
  for (const auto& p : synth::generateTrajectory(script)) {
    cv::Mat grey;
    renderer.render(p.pose).convertTo(grey, CV_8U);
    out.push_back(grey);
  }
  return out;
}

/// Copies a dataset directory (so a test can damage its copy).
inline void copyDataset(const fs::path& from, const fs::path& to) {
  fs::copy(from, to, fs::copy_options::recursive);
}

inline void writeText(const fs::path& path, const std::string& text) {
  std::ofstream out(path);
  out << text;
  if (!out) throw std::runtime_error("cannot write " + path.string());
}

/// File name of frame i of a rendered dataset ("000007.png").
inline std::string frameName(int i) {
  char name[16];
  std::snprintf(name, sizeof name, "%06d.png", i);
  return name;
}

/// Writes DATASET/timestamps.txt: frame i < `frames` at stamp(i) seconds (17 digits).
inline void writeTimestamps(const fs::path& dataset, int frames,
                            const std::function<double(int)>& stamp) {
  std::ostringstream text;
  text.precision(17);
  for (int i = 0; i < frames; ++i) text << frameName(i) << " " << stamp(i) << "\n";
  writeText(dataset / "timestamps.txt", text.str());
}

/// "name seconds" lines of DATASET/timestamps.txt.
inline std::map<std::string, double> readTimestamps(const fs::path& dataset) {
  std::map<std::string, double> stamps;
  std::ifstream in(dataset / "timestamps.txt");
  std::string name;
  double t = 0;
  while (in >> name >> t) stamps[name] = t;
  return stamps;
}

/// Angle of the rotation R_a^T R_b, radians.
inline double rotationError(const Eigen::Matrix3d& a, const Eigen::Matrix3d& b) {
  return Eigen::AngleAxisd(a.transpose() * b).angle();
}

inline Eigen::Matrix3d poseRotation(const pose_t& p) {
  return Eigen::Quaterniond(p.orientation[0], p.orientation[1], p.orientation[2], p.orientation[3])
      .normalized()
      .toRotationMatrix();
}

inline Eigen::Matrix3d relativeRotation(const pose_t& p) {
  return rotationFromVector(
      Eigen::Vector3d(p.rotation_vector[0], p.rotation_vector[1], p.rotation_vector[2]));
}

/// Every message of an LCM log file, decoded with the generated types, in log order.
struct DecodedLog {
  struct Entry {
    std::string channel;
    int index = -1;  ///< into poses / statuses / diagnostics
  };
  std::vector<Entry> order;
  std::vector<pose_t> poses;
  std::vector<status_t> statuses;
  std::vector<fit_diagnostics_t> diagnostics;
  std::vector<std::int64_t> pose_log_utime;  ///< event timestamp of each pose (publish time)
  int undecodable = 0;
  std::set<std::string> channels;
};

inline DecodedLog readLcmLog(const fs::path& path, const std::string& pose_channel = "OMNI_POSE",
                             const std::string& status_channel = "OMNI_STATUS",
                             const std::string& fit_channel = "OMNI_FIT") {
  DecodedLog log;
  lcm::LogFile file(path.string(), "r");
  if (!file.good()) throw std::runtime_error("cannot read LCM log " + path.string());
  while (const lcm::LogEvent* e = file.readNextEvent()) {
    log.channels.insert(e->channel);
    if (e->channel == pose_channel) {
      pose_t p;
      if (p.decode(e->data, 0, e->datalen) != e->datalen) { ++log.undecodable; continue; }
      log.order.push_back({e->channel, static_cast<int>(log.poses.size())});
      log.poses.push_back(p);
      log.pose_log_utime.push_back(e->timestamp);
    } else if (e->channel == status_channel) {
      status_t s;
      if (s.decode(e->data, 0, e->datalen) != e->datalen) { ++log.undecodable; continue; }
      log.order.push_back({e->channel, static_cast<int>(log.statuses.size())});
      log.statuses.push_back(s);
    } else if (e->channel == fit_channel) {
      fit_diagnostics_t d;
      if (d.decode(e->data, 0, e->datalen) != e->datalen) { ++log.undecodable; continue; }
      log.order.push_back({e->channel, static_cast<int>(log.diagnostics.size())});
      log.diagnostics.push_back(d);
    }
  }
  return log;
}

/// One message of an LCM log: its channel and encoded bytes.
struct LcmEvent {
  std::string channel;
  std::vector<std::uint8_t> bytes;
};

/// An omnipose.imu_t message of `sample` (utime = t in microseconds; accel zero).
inline LcmEvent imuEvent(const GyroSample& sample, const std::string& channel = "OMNI_IMU") {
  imu_t m;
  m.utime = static_cast<std::int64_t>(std::llround(sample.t * 1e6));
  for (int i = 0; i < 3; ++i) {
    m.gyro[i] = sample.rate[i];
    m.accel[i] = 0.0;
  }
  LcmEvent e{channel, std::vector<std::uint8_t>(static_cast<std::size_t>(m.getEncodedSize()))};
  m.encode(e.bytes.data(), 0, static_cast<int>(e.bytes.size()));
  return e;
}

/// Writes `events` as an LCM log at `path`, 1 ms apart (throws when it cannot).
inline void writeLcmLog(const fs::path& path, const std::vector<LcmEvent>& events) {
  lcm::LogFile file(path.string(), "w");
  if (!file.good()) throw std::runtime_error("cannot write LCM log " + path.string());
  lcm::LogEvent event{};
  event.timestamp = 1'000'000;
  for (const LcmEvent& e : events) {
    event.eventnum = 0;
    event.timestamp += 1000;
    event.channel = e.channel;
    event.datalen = static_cast<std::int32_t>(e.bytes.size());
    event.data = const_cast<std::uint8_t*>(e.bytes.data());
    if (file.writeEvent(&event) != 0) throw std::runtime_error("cannot write " + path.string());
  }
}

/// A daemon config (YAML text) for a file source.
inline std::string fileSourceConfig(const fs::path& dataset, const std::string& lcm_url,
                                    bool realtime, bool loop = false,
                                    const std::string& extra_lcm = "") {
  std::ostringstream o;
  o << "source:\n  type: file\n  path: " << dataset.string() << "\n  realtime: "
    << (realtime ? "true" : "false") << "\n  loop: " << (loop ? "true" : "false") << "\n"
    << "calibration: " << (dataset / "calibration.yaml").string() << "\n"
    << "lcm:\n  url: \"" << lcm_url << "\"\n"
    << extra_lcm;
  return o.str();
}

/// A child process with stdout/stderr in files.
class Child {
 public:
  /// `extra_env`: "NAME=value" entries added to this process's environment.
  Child(const std::vector<std::string>& argv, const fs::path& stdout_path,
        const fs::path& stderr_path, const std::vector<std::string>& extra_env = {}) {
    posix_spawn_file_actions_t actions;
    posix_spawn_file_actions_init(&actions);
    posix_spawn_file_actions_addopen(&actions, 1, stdout_path.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    posix_spawn_file_actions_addopen(&actions, 2, stderr_path.c_str(),
                                     O_WRONLY | O_CREAT | O_TRUNC, 0644);
    // The child starts with no blocked signals and default dispositions.
    posix_spawnattr_t attr;
    posix_spawnattr_init(&attr);
    sigset_t none, all;
    sigemptyset(&none);
    sigfillset(&all);
    posix_spawnattr_setsigmask(&attr, &none);
    posix_spawnattr_setsigdefault(&attr, &all);
    posix_spawnattr_setflags(&attr, POSIX_SPAWN_SETSIGMASK | POSIX_SPAWN_SETSIGDEF);
    std::vector<char*> args;
    for (const auto& a : argv) args.push_back(const_cast<char*>(a.c_str()));
    args.push_back(nullptr);
    std::vector<char*> env;
    for (char** e = environ; *e; ++e) env.push_back(*e);
    for (const auto& e : extra_env) env.push_back(const_cast<char*>(e.c_str()));
    env.push_back(nullptr);
    const int rc = posix_spawn(&pid_, args[0], &actions, &attr, args.data(), env.data());
    posix_spawn_file_actions_destroy(&actions);
    posix_spawnattr_destroy(&attr);
    if (rc != 0) throw std::runtime_error("cannot start " + argv[0]);
  }
  ~Child() {
    if (pid_ > 0 && !exited_) {
      ::kill(pid_, SIGKILL);
      int status = 0;
      waitpid(pid_, &status, 0);
    }
  }
  Child(const Child&) = delete;
  Child& operator=(const Child&) = delete;

  void signal(int sig) { ::kill(pid_, sig); }
  pid_t pid() const { return pid_; }
  /// Exit code (128 + signal when killed by a signal), or -1 after `timeout`.
  int wait(std::chrono::milliseconds timeout) {
    const auto deadline = std::chrono::steady_clock::now() + timeout;
    for (;;) {
      int status = 0;
      rusage usage{};
      const pid_t r = wait4(pid_, &status, WNOHANG, &usage);
      if (r == pid_) {
        exited_ = true;
        max_rss_kb_ = usage.ru_maxrss;
        if (WIFEXITED(status)) return WEXITSTATUS(status);
        if (WIFSIGNALED(status)) return 128 + WTERMSIG(status);
        return -1;
      }
      if (std::chrono::steady_clock::now() > deadline) return -1;
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  }
  bool running() {
    int status = 0;
    return waitpid(pid_, &status, WNOHANG) == 0;
  }
  /// The child's peak resident set size in kB, once wait() has seen it exit.
  long maxRssKb() const { return max_rss_kb_; }

 private:
  pid_t pid_ = -1;
  bool exited_ = false;
  long max_rss_kb_ = 0;
};

/// Runs a command line, returns its exit code; output in the given files.
inline int runProcess(const std::vector<std::string>& argv, const fs::path& out,
                      const fs::path& err, std::chrono::milliseconds timeout) {
  Child child(argv, out, err);
  return child.wait(timeout);
}

/// An in-memory frame source (preloaded frames, ping-pong order so consecutive frames are
/// always one motion step apart), with scripted faults at given delivery numbers. Its next()
/// copies into the caller's buffer and allocates nothing.
class MemorySource final : public FrameSource {
 public:
  struct Script {
    std::chrono::microseconds period{0};  ///< 0: a frame per call, at once
    long total = -1;                      ///< deliveries before kEndOfStream (-1 = endless)
    std::set<long> bad;                   ///< deliveries that return kBadFrame
    std::set<long> disconnect;            ///< deliveries that return kDisconnected
  };
  MemorySource(std::vector<cv::Mat> frames, Script script)
      : frames_(std::move(frames)), script_(std::move(script)) {}

  Expected<void> open() override {
    ++opens_;
    return {};
  }
  cv::Size frameSize() const override { return frames_.front().size(); }
  Expected<FrameInfo> next(cv::Mat& out, std::chrono::milliseconds) override {
    if (script_.total >= 0 && delivery_ >= script_.total)
      return fail(ErrorCode::kEndOfStream, "memory: end");
    if (script_.period.count() > 0) {
      if (next_due_ == std::chrono::steady_clock::time_point{}) next_due_ = std::chrono::steady_clock::now();
      std::this_thread::sleep_until(next_due_);
      next_due_ += script_.period;
    }
    const long n = delivery_++;
    if (script_.disconnect.contains(n)) return fail(ErrorCode::kDisconnected, "memory: unplugged at %ld", n);
    if (script_.bad.contains(n)) return fail(ErrorCode::kBadFrame, "memory frame %ld: corrupt", n);
    const long cycle = 2 * static_cast<long>(frames_.size()) - 2;
    long k = cycle > 0 ? n % cycle : 0;
    if (k >= static_cast<long>(frames_.size())) k = cycle - k;
    frames_[static_cast<std::size_t>(k)].copyTo(out);
    FrameInfo info;
    info.sequence = static_cast<std::uint64_t>(n);
    info.capture_time_us = std::chrono::duration_cast<std::chrono::microseconds>(
                               std::chrono::system_clock::now().time_since_epoch())
                               .count();
    info.index = -1;
    return info;
  }
  void close() override {}
  std::string describe() const override { return "memory (" + std::to_string(frames_.size()) + " frames)"; }
  int opens() const { return opens_; }

 private:
  std::vector<cv::Mat> frames_;
  Script script_;
  long delivery_ = 0;
  int opens_ = 0;
  std::chrono::steady_clock::time_point next_due_{};
};

}  // namespace omnipose::testing
