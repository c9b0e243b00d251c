/// omnipose-listen: a small LCM client that prints the poses (and status) omniposed
/// publishes, one line per message, as a user or a controller developer would watch them.
///
///   omnipose-listen [--url URL] [--channel OMNI_POSE] [--status-channel OMNI_STATUS]
///                   [--count N] [--timeout SECONDS]

#include <lcm/lcm-cpp.hpp>

#include <charconv>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <string>

#include "omnipose/pose_t.hpp"
#include "omnipose/status_t.hpp"

namespace {

volatile std::sig_atomic_t g_stop = 0;
void onSignal(int) { g_stop = 1; }

constexpr const char* kUsage =
    "usage: omnipose-listen [--url URL] [--channel OMNI_POSE] [--status-channel OMNI_STATUS]\n"
    "                       [--count N] [--timeout SECONDS]\n"
    "\n"
    "  --url URL              LCM URL (default: LCM's default, udpm multicast; a log file:\n"
    "                         file:///path/run.lcm?speed=0 replays it as fast as possible)\n"
    "  --channel NAME         pose channel (default OMNI_POSE)\n"
    "  --status-channel NAME  status channel (default OMNI_STATUS; \"\" = do not print status)\n"
    "  --count N              exit after N poses (default: run until Ctrl-C)\n"
    "  --timeout SECONDS      exit (code 3) when no message arrived for this long (default: never)\n";

const char* statusName(std::int8_t status) {
  switch (status) {
    case omnipose::pose_t::STATUS_OK: return "ok";
    case omnipose::pose_t::STATUS_DEGRADED: return "degraded";
    case omnipose::pose_t::STATUS_LOST: return "lost";
  }
  return "?";
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
  }

  void onStatus(const lcm::ReceiveBuffer*, const std::string&, const omnipose::status_t* s) {
    got_message = true;
    std::printf("status%s: received %" PRId64 " processed %" PRId64 " skipped %" PRId64
                " bad %" PRId64 " lost upstream %" PRId64 " lost poses %" PRId64
                " source failures %" PRId64
                " | %.1f / %.1f Hz | processing p50 %.1f p99 %.1f ms | latency p50 %.1f p99 "
                "%.1f ms | source %s (%s)%s%s\n",
                s->final ? " (final)" : "", s->frames_received, s->frames_processed,
                s->frames_skipped_stale, s->frames_bad, s->frames_lost_upstream, s->poses_lost, s->source_failures,
                s->receive_rate_hz, s->process_rate_hz, s->processing_ms_p50,
                s->processing_ms_p99, s->latency_ms_p50, s->latency_ms_p99,
                sourceStateName(s->source_state), s->source.c_str(),
                s->last_error.empty() ? "" : " | last error: ", s->last_error.c_str());
    std::fflush(stdout);
  }
};

bool parseNumber(const char* text, double& out) {
  const std::string s = text;
  const auto [end, ec] = std::from_chars(s.data(), s.data() + s.size(), out);
  return ec == std::errc() && end == s.data() + s.size();
}

}  // namespace

int main(int argc, char** argv) {
  std::string url, pose_channel = "OMNI_POSE", status_channel = "OMNI_STATUS";
  double count = 0, timeout = 0;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    const bool has_value = i + 1 < argc;
    if (arg == "-h" || arg == "--help") {
      std::fputs(kUsage, stdout);
      return 0;
    } else if (arg == "--url" && has_value) {
      url = argv[++i];
    } else if (arg == "--channel" && has_value) {
      pose_channel = argv[++i];
    } else if (arg == "--status-channel" && has_value) {
      status_channel = argv[++i];
    } else if (arg == "--count" && has_value && parseNumber(argv[i + 1], count) && count >= 0) {
      ++i;
    } else if (arg == "--timeout" && has_value && parseNumber(argv[i + 1], timeout) && timeout >= 0) {
      ++i;
    } else {
      std::fprintf(stderr, "omnipose-listen: bad argument '%s'\n%s", arg.c_str(), kUsage);
      return 2;
    }
  }

  lcm::LCM lcm(url);
  if (!lcm.good()) {
    std::fprintf(stderr, "omnipose-listen: cannot initialise LCM with URL \"%s\"\n", url.c_str());
    return 1;
  }
  std::signal(SIGINT, onSignal);
  std::signal(SIGTERM, onSignal);

  Printer printer;
  lcm.subscribe(pose_channel, &Printer::onPose, &printer);
  if (!status_channel.empty()) lcm.subscribe(status_channel, &Printer::onStatus, &printer);

  auto last_message = std::chrono::steady_clock::now();
  while (!g_stop) {
    const int handled = lcm.handleTimeout(100);
    if (handled < 0) break;  // LCM error, or the end of a log file
    const auto now = std::chrono::steady_clock::now();
    if (printer.got_message) {
      printer.got_message = false;
      last_message = now;
    } else if (timeout > 0 && now - last_message > std::chrono::duration<double>(timeout)) {
      std::fprintf(stderr, "omnipose-listen: no message for %.1f s\n", timeout);
      return 3;
    }
    if (count > 0 && printer.poses >= static_cast<long>(count)) break;
  }
  return 0;
}
