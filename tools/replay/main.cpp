// omnipose-replay: estimates the camera motion of a recorded dataset directory, headless.
// Exit codes: 0 done, 1 failed (dataset, calibration, no pair estimated), 2 bad command line.
#include <cstdio>
#include <exception>
#include <string>

#include "cli.hpp"
#include "replay.hpp"
#include "quiet_opencv.hpp"

namespace {

/// The command line, as parsed.
struct Args {
  std::string dataset, input, out_tum, out_odometry_tum, relative_csv, config, calibration;
  std::string method = omnipose::replay::ReplayOptions{}.method;
  std::string map_in, map_out;
  int from = 0, count = 0;
  bool quiet = false;
};

void addOptions(CLI::App& app, Args& a) {
  std::string methods;
  for (const auto& m : omnipose::replay::methodNames()) methods += (methods.empty() ? "" : "|") + m;
  app.add_option("DATASET", a.dataset,
                 "directory with calibration.yaml, frames/, optional timestamps.txt and "
                 "groundtruth.tum")
      ->required();
  app.add_option("--out", a.out_tum,
                 "TUM trajectory to write (timestamp s, position, quaternion; first frame at "
                 "identity; position up to scale): the map pose, corrected by loop closures")
      ->type_name("EST.tum");
  app.add_option("--out-odometry", a.out_odometry_tum,
                 "TUM trajectory of the odometry's own pose (continuous, never corrected by a "
                 "loop closure; the same as --out with loop_closure off)")
      ->type_name("ODOM.tum");
  app.add_option("--relative", a.relative_csv,
                 "per-pair CSV: rotation vector (rad), translation direction (unit), |tau|, "
                 "residual (px), windows used, status, track state, segment, keyframe, seconds "
                 "in all and per stage (unwrap, registration, fit, refinement)")
      ->type_name("REL.csv");
  app.add_option("--input", a.input, "frames are omni donuts (default) or panoramas")
      ->type_name("omni|panorama")
      ->check(omnipose::tools::oneOf({"omni", "panorama"}));
  app.add_option("--config", a.config,
                 "daemon.yaml whose input/pipeline sections are used")
      ->type_name("daemon.yaml");
  app.add_option("--calibration", a.calibration,
                 "calibration YAML instead of DATASET/calibration.yaml")
      ->type_name("CAL.yaml");
  app.add_option("--method", a.method,
                 "ifmi (default, this project) | orb5pt | akaze5pt | orbrot | akazerot (the "
                 "feature-based baselines: ORB/AKAZE with OpenGV 5-point or 2-point "
                 "rotation-only RANSAC)")
      ->type_name(methods)
      ->check(omnipose::tools::oneOf(omnipose::replay::methodNames()));
  app.add_option("--from", a.from, "start at this frame (dataset order, from 0)")
      ->type_name("INDEX")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--count", a.count, "replay at most this many frames (0: to the end)")
      ->type_name("N")
      ->check(CLI::NonNegativeNumber);
  app.add_option("--map-in", a.map_in,
                 "a map saved by --map-out or by omniposed (loop_closure.map_file) to start "
                 "with: the frames find where they are in it, then the map pose is in its frame")
      ->type_name("MAP");
  app.add_option("--map-out", a.map_out, "save the map after the last frame")->type_name("MAP");
  app.add_flag("--quiet", a.quiet, "no progress line (it is shown only on a terminal anyway)");
}

/// The replay's options from the command line: the optional paths only when given (even as "").
omnipose::replay::ReplayOptions replayOptions(const CLI::App& app, const Args& a) {
  omnipose::replay::ReplayOptions options;
  options.dataset = a.dataset;
  options.method = a.method;
  auto given = [&](const char* flag) { return app.count(flag) > 0; };
  if (given("--out")) options.out_tum = a.out_tum;
  if (given("--out-odometry")) options.out_odometry_tum = a.out_odometry_tum;
  if (given("--relative")) options.relative_csv = a.relative_csv;
  if (given("--config")) options.config = a.config;
  if (given("--calibration")) options.calibration = a.calibration;
  if (given("--map-in")) options.map_in = a.map_in;
  if (given("--map-out")) options.map_out = a.map_out;
  options.from = a.from;
  options.count = a.count;
  options.progress = !a.quiet;
  if (a.input == "omni") options.input = omnipose::InputKind::kOmni;
  else if (a.input == "panorama") options.input = omnipose::InputKind::kPanorama;
  return options;
}

constexpr const char* kUsage =
    "usage: omnipose-replay DATASET [--out EST.tum] [--out-odometry ODOM.tum]\n"
    "                       [--relative REL.csv]\n"
    "                       [--input omni|panorama] [--config daemon.yaml]\n"
    "                       [--calibration CAL.yaml] [--method NAME] [--from INDEX]\n"
    "                       [--count N] [--map-in MAP] [--map-out MAP] [--quiet]";

constexpr const char* kDescription =
    "Estimates the camera motion of every consecutive frame pair of a dataset directory.\n"
    "Ends with: frames=N pairs=M skipped=K implausible=I lost=L bridged=B seconds_per_frame=X\n"
    "loops=C places=P (skipped: unreadable frames and the I implausible ones, decoded but not\n"
    "believed: a glitching camera; X: median wall time per frame, seconds; C: frames that\n"
    "closed a loop with a place seen before; P: places in the memory at the end; with --map-in,\n"
    "relocalised=F: the frame that found the loaded map, -1 if none). Exit codes: 0 done, 1 failed (or no pair estimated), 2 bad command line.";

}  // namespace

int main(int argc, char** argv) {
  omnipose::tools::quietOpenCvWarnings();
  return omnipose::tools::runMain<Args>(
      argc, argv, {"omnipose-replay", kUsage, kDescription}, addOptions,
      [](omnipose::tools::Cli& cli, const Args& args) {
        const auto s = omnipose::replay::run(replayOptions(cli.app(), args), stderr);
        std::printf("frames=%d pairs=%d skipped=%d implausible=%d lost=%d bridged=%d "
                    "seconds_per_frame=%.6f loops=%d places=%d",
                    s.frames, s.pairs, s.skipped, s.implausible, s.lost, s.bridged,
                    s.median_seconds_per_frame, s.loops_closed, s.places);
        if (cli.app().count("--map-in") > 0) std::printf(" relocalised=%d", s.relocalised_at);
        std::printf("\n");
        return s.pairs > 0 || s.frames == 1 ? 0 : 1;
      });
}
