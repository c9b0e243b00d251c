// omnipose-replay: estimates the camera motion of a recorded dataset directory, headless.
#include <cstdio>
#include <cstring>
#include <exception>
#include <string>

#include "replay.hpp"

namespace {

void usage(std::FILE* out) {
  std::fprintf(out,
               "usage: omnipose-replay DATASET [--out EST.tum] [--relative REL.csv]\n"
               "                       [--input omni|panorama] [--config daemon.yaml]\n"
               "                       [--calibration CAL.yaml] [--method NAME] [--quiet]\n"
               "  DATASET      directory with calibration.yaml, frames/, optional\n"
               "               timestamps.txt and groundtruth.tum\n"
               "  --out        TUM trajectory (first frame at identity)\n"
               "  --relative   per-pair CSV: rotation vector, translation direction, |tau|,\n"
               "               residual, windows used, status\n"
               "  --input      frames are omni donuts (default) or panoramas\n"
               "  --config     daemon.yaml whose input/pipeline sections are used\n"
               "  --method     ifmi (default) | orb5pt | akaze5pt | orbrot | akazerot\n"
               "               (the feature-based baselines: ORB/AKAZE with OpenGV 5-point\n"
               "               or 2-point rotation-only RANSAC)\n"
               "Ends with: frames=N pairs=M skipped=K seconds_per_frame=X\n");
}

}  // namespace

int main(int argc, char** argv) {
  omnipose::replay::ReplayOptions options;
  bool have_dataset = false;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    auto value = [&](const char* name) -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "omnipose-replay: %s needs a value\n", name);
        std::exit(2);
      }
      return argv[++i];
    };
    if (arg == "-h" || arg == "--help") {
      usage(stdout);
      return 0;
    } else if (arg == "--out") {
      options.out_tum = value("--out");
    } else if (arg == "--relative") {
      options.relative_csv = value("--relative");
    } else if (arg == "--config") {
      options.config = value("--config");
    } else if (arg == "--calibration") {
      options.calibration = value("--calibration");
    } else if (arg == "--method") {
      options.method = value("--method");
    } else if (arg == "--quiet") {
      options.progress = false;
    } else if (arg == "--input") {
      const std::string kind = value("--input");
      if (kind == "omni") options.input = omnipose::InputKind::kOmni;
      else if (kind == "panorama") options.input = omnipose::InputKind::kPanorama;
      else {
        std::fprintf(stderr, "omnipose-replay: --input must be omni or panorama, not '%s'\n",
                     kind.c_str());
        return 2;
      }
    } else if (!arg.empty() && arg[0] == '-') {
      std::fprintf(stderr, "omnipose-replay: unknown option %s\n", arg.c_str());
      usage(stderr);
      return 2;
    } else if (!have_dataset) {
      options.dataset = arg;
      have_dataset = true;
    } else {
      std::fprintf(stderr, "omnipose-replay: more than one dataset given (%s)\n", arg.c_str());
      return 2;
    }
  }
  if (!have_dataset) {
    usage(stderr);
    return 2;
  }
  try {
    const auto s = omnipose::replay::run(options, stderr);
    std::printf("frames=%d pairs=%d skipped=%d seconds_per_frame=%.6f\n", s.frames, s.pairs,
                s.skipped, s.median_seconds_per_frame);
    return s.pairs > 0 || s.frames == 1 ? 0 : 1;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "omnipose-replay: %s\n", e.what());
    return 1;
  }
}
