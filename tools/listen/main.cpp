/// omnipose-listen: a small LCM client that prints the poses (and status) omniposed
/// publishes, one line per message, as a user or a controller developer would watch them.
///
///   omnipose-listen [--url URL] [--channel OMNI_POSE] [--status-channel OMNI_STATUS]
///                   [--count N] [--timeout SECONDS] [--tum OUT.tum]
///
/// --tum also writes every pose's chained pose as a TUM line (`timestamp tx ty tz qx qy qz
/// qw`): the timestamp is the recorded one (source_timestamp) for a file source, else the
/// capture time utime in seconds; position in units of rho, full precision.

#include <lcm/lcm-cpp.hpp>

#include <cerrno>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>

#include "cli.hpp"
#include "common/named_values.hpp"
#include "daemon/counters.hpp"
#include "omnipose/file_io.hpp"
#include "omnipose/pose_t.hpp"
#include "omnipose/status_t.hpp"

namespace {

volatile std::sig_atomic_t g_stop = 0;
void onSignal(int) { g_stop = 1; }

const char* statusName(std::int8_t status) {
  using omnipose::pose_t;
  constexpr omnipose::detail::Named<std::int8_t> kNames[] = {
      {pose_t::STATUS_OK, "ok"}, {pose_t::STATUS_DEGRADED, "degraded"}, {pose_t::STATUS_LOST, "lost"}};
  return omnipose::detail::nameOf(kNames, status);
}

const char* sourceStateName(std::int8_t state) {
  switch (state) {
    case omnipose::status_t::SOURCE_STARTING: return "starting";
    case omnipose::status_t::SOURCE_STREAMING: return "streaming";
    case omnipose::status_t::SOURCE_RECONNECTING: return "reconnecting";
    case omnipose::status_t::SOURCE_ENDED: return "ended";
    case omnipose::status_t::SOURCE_STOPPED: return "stopped";
  }
  return "?";
}

struct Printer {
  long poses = 0;
  bool got_message = false;
  std::FILE* tum = nullptr;  ///< --tum file, or none
  bool tum_failed = false;

  void onPose(const lcm::ReceiveBuffer*, const std::string&, const omnipose::pose_t* p) {
    got_message = true;
    ++poses;
    const double angle = std::sqrt(p->rotation_vector[0] * p->rotation_vector[0] +
                                   p->rotation_vector[1] * p->rotation_vector[1] +
                                   p->rotation_vector[2] * p->rotation_vector[2]);
    std::printf("pose seq %" PRId64 " t %.6f seg %d %-8s q(wxyz) %+.5f %+.5f %+.5f %+.5f "
                "p %+.4f %+.4f %+.4f | rel rot %+.5f %+.5f %+.5f (%.3f deg) tdir %+.3f %+.3f "
                "%+.3f |tau| %.4f | res %.3f px win %d/%d skip %d\n",
                p->sequence, static_cast<double>(p->utime) * 1e-6, p->segment,
                statusName(p->status), p->orientation[0], p->orientation[1], p->orientation[2],
                p->orientation[3], p->position[0], p->position[1], p->position[2],
                p->rotation_vector[0], p->rotation_vector[1], p->rotation_vector[2],
                angle * 180.0 / M_PI, p->translation_direction[0], p->translation_direction[1],
                p->translation_direction[2], p->tau_norm, p->residual_px, p->windows_used,
                p->windows_total, p->frames_skipped);
    std::fflush(stdout);
    if (tum) {
      const double t = p->source_index >= 0 ? p->source_timestamp
                                            : static_cast<double>(p->utime) * 1e-6;
      if (std::fprintf(tum, "%.6f %.9g %.9g %.9g %.12g %.12g %.12g %.12g\n", t, p->position[0],
                       p->position[1], p->position[2], p->orientation[1], p->orientation[2],
                       p->orientation[3], p->orientation[0]) < 0) {
        tum_failed = true;
      }
    }
  }

  void onStatus(const lcm::ReceiveBuffer*, const std::string&, const omnipose::status_t* s) {
    got_message = true;
    // "status: received N processed N skipped (stale) N ...": every counter of the daemon's
    // table (src/daemon/counters.hpp), by its label.
    std::printf("status%s:", s->final ? " (final)" : "");
    omnipose::daemon::forEachCounter(*s, [](const char* label, std::int64_t value) {
      std::printf(" %s %" PRId64, label, value);
    });
    std::printf(" | %.1f / %.1f Hz | processing p50 %.1f p99 %.1f ms | latency p50 %.1f p99 "
                "%.1f ms | cpu %.2f cores, pipeline on cpu %.0f %%, worker wait %.2f ms/frame"
                " in %.0f %% of frames, threads %d of %d | source %s (%s)%s%s\n",
                s->receive_rate_hz, s->process_rate_hz, s->processing_ms_p50,
                s->processing_ms_p99, s->latency_ms_p50, s->latency_ms_p99, s->cpu_cores,
                100.0 * s->processing_cpu_share, s->worker_wait_ms,
                100.0 * s->frames_waited_share, s->threads_active, s->threads,
                sourceStateName(s->source_state), s->source.c_str(),
                s->last_error.empty() ? "" : " | last error: ", s->last_error.c_str());
    std::fflush(stdout);
  }
};

/// The command line, as parsed.
struct Args {
  std::string url, pose_channel = "OMNI_POSE", status_channel = "OMNI_STATUS", tum_path;
  double count = 0, timeout = 0;
};

void addOptions(CLI::App& app, Args& a) {
  app.add_option("--url", a.url,
                 "LCM URL (default: LCM's default, udpm multicast; a log file: "
                 "file:///path/run.lcm?speed=0 replays it as fast as possible)");
  app.add_option("--channel", a.pose_channel, "pose channel")
      ->type_name("NAME")
      ->capture_default_str();
  app.add_option("--status-channel", a.status_channel,
                 "status channel (\"\" = do not print status)")
      ->type_name("NAME")
      ->capture_default_str();
  app.add_option("--count", a.count, "exit after N poses (default: run until Ctrl-C)")
      ->type_name("N")
      ->check(omnipose::tools::nonNegative());
  app.add_option("--timeout", a.timeout,
                 "exit (code 3) when no message arrived for this long, seconds (default: never)")
      ->type_name("SECONDS")
      ->check(omnipose::tools::nonNegative());
  app.add_option("--tum", a.tum_path,
                 "also write every pose's chained pose to OUT.tum (TUM: timestamp tx ty tz qx "
                 "qy qz qw; the recorded timestamp for a file source, else utime in seconds)")
      ->type_name("OUT.tum");
}

/// Subscribes and prints until a stop signal, --count poses, the end of a log or --timeout.
int listen(const Args& a) {
  Printer printer;
  struct FileCloser {
    void operator()(std::FILE* f) const { std::fclose(f); }
  };
  std::unique_ptr<std::FILE, FileCloser> tum;
  if (!a.tum_path.empty()) {
    tum.reset(std::fopen(a.tum_path.c_str(), "w"));
    if (!tum) {
      std::fprintf(stderr, "omnipose-listen: %s: cannot write: %s\n", a.tum_path.c_str(),
                   std::strerror(errno));
      return 1;
    }
    std::fprintf(tum.get(), "# timestamp tx ty tz qx qy qz qw (omnipose-listen, channel %s)\n",
                 a.pose_channel.c_str());
    printer.tum = tum.get();
  }

  // A recorded log is read by LCM's file provider, whose fopen() blocks on a FIFO: anything
  // that is not a regular file is refused by name first.
  if (a.url.rfind("file://", 0) == 0) {
    const std::string rest = a.url.substr(7);
    const std::string path = rest.substr(0, rest.find('?'));
    if (const omnipose::Expected<void> ok = omnipose::checkRegularFile(path); !ok) {
      std::fprintf(stderr, "omnipose-listen: --url \"%s\": %s\n", a.url.c_str(), ok.error().c_str());
      return 1;
    }
  }
  lcm::LCM lcm(a.url);
  if (!lcm.good()) {
    std::fprintf(stderr, "omnipose-listen: cannot initialise LCM with URL \"%s\"\n", a.url.c_str());
    return 1;
  }
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);

  lcm.subscribe(a.pose_channel, &Printer::onPose, &printer);
  if (!a.status_channel.empty()) lcm.subscribe(a.status_channel, &Printer::onStatus, &printer);

  auto last_message = std::chrono::steady_clock::now();
  while (!g_stop) {
    const int handled = lcm.handleTimeout(100);
    if (handled < 0) break;  // LCM error, or the end of a log file
    const auto now = std::chrono::steady_clock::now();
    if (printer.got_message) {
      printer.got_message = false;
      last_message = now;
    } else if (a.timeout > 0 && now - last_message > std::chrono::duration<double>(a.timeout)) {
      std::fprintf(stderr, "omnipose-listen: no message for %.1f s\n", a.timeout);
      return 3;
    }
    if (a.count > 0 && printer.poses >= static_cast<long>(a.count)) break;
  }
  if (tum && (printer.tum_failed || std::fclose(tum.release()) != 0)) {
    std::fprintf(stderr, "omnipose-listen: %s: cannot write\n", a.tum_path.c_str());
    return 1;
  }
  return 0;
}

constexpr const char* kUsage =
    "usage: omnipose-listen [--url URL] [--channel OMNI_POSE] [--status-channel OMNI_STATUS]\n"
    "                       [--count N] [--timeout SECONDS] [--tum OUT.tum]";

constexpr const char* kDescription =
    "Prints the poses (and status) omniposed publishes over LCM, one line per message.\n"
    "Exit codes: 0 done (Ctrl-C, --count reached, end of a log), 1 LCM failed or OUT.tum\n"
    "cannot be written, 2 bad command line, 3 --timeout expired.";

}  // namespace

int main(int argc, char** argv) {
  return omnipose::tools::runMain<Args>(argc, argv, {"omnipose-listen", kUsage, kDescription},
                                        addOptions, [](auto&, const Args& args) { return listen(args); });
}
