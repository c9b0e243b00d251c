// Per-frame instruction counts of the pipeline (paper setting), for valgrind --tool=callgrind
// (x86) and for an instruction-counting emulator run (arm64): renders the benchmark's two
// frames (3 degrees of roll + yaw apart), makes a Pipeline, processes --warmup frames and
// then --frames frames, and prints the wall time. Under callgrind only the measured frames
// are counted (CALLGRIND_TOGGLE_COLLECT around them; run with --collect-atstart=no):
//   valgrind --tool=callgrind --collect-atstart=no build/bin/omnipose-bench-instructions --frames 10
//   -> "Collected" instructions / 10 = instructions per frame.
// Usage: omnipose-bench-instructions [--threads N] [--frames K] [--warmup W]
//                                    [--refine R] [--wisdom FILE] [--save DIR | --load DIR]
//                                    [--odometry [--readout S [--gyro HZ]] [--keyframe-slots N]]
//                                    [--no-moving-content] [--no-ring-consensus]
//                                    [--noise-weighting] [--translation-shrinkage K]
//                                    [--planar-motion-deg D]
// --odometry processes the frames with Odometry (what omniposed and omnipose-replay run),
// stamped at 30 fps, instead of Pipeline (its default keyframes: the first frame stays in
// reach, so every frame is registered against it as well; --keyframe-slots 0 counts
// frame-to-frame chaining); --readout S gives the calibration a rolling
// shutter of S seconds (the rows' capture times corrected in every pass), --gyro HZ gives it
// a gyro sampled at HZ (the calibration's imu section; the rows' rotations from the gyro).
// --no-moving-content turns the refinement pass's check for content moving on its own off
// (PipelineOptions::moving_content), to count what it costs; --no-ring-consensus turns the
// fit's ring consensus off (MotionFit::Options::ring_consensus), likewise; --noise-weighting
// turns the registration's signal-to-noise weighting on
// (WindowRegistration::Options::noise_weighting); --vertical-scale takes the fit's scale
// equations from each window's vertical scale (MotionFit::Options::vertical_scale);
// --translation-shrinkage K sets the fit's
// MotionFit::Options::translation_shrinkage (0: off); --planar-motion-deg D sets the fit's
// MotionFit::Options::planar_motion_deg (0: tau_z free).
// --save writes the two rendered frames to DIR/a.png, DIR/b.png; --load reads them instead
// of rendering (an emulator then spends nothing on the renderer).
#include <chrono>
#include <cstdio>
#include <algorithm>
#include <array>
#include <cstdlib>
#include <filesystem>
#include <optional>
#include <opencv2/imgcodecs.hpp>
#include <stdexcept>
#include <string>
#include <vector>
#include <cmath>

#include "cli.hpp"
#include "omnipose/io/trajectory.hpp"
#include "omnipose/odometry.hpp"
#include "omnipose/pipeline.hpp"
#include "omnipose/synth/synth.hpp"
#include "quiet_opencv.hpp"

#if __has_include(<valgrind/callgrind.h>)
#include <valgrind/callgrind.h>
#define OMNIPOSE_TOGGLE_COLLECT() CALLGRIND_TOGGLE_COLLECT
#else
#define OMNIPOSE_TOGGLE_COLLECT() \
  do {                            \
  } while (false)
#endif

namespace {

/// The command line, as parsed.
struct Args {
  int threads = 1, frames = 10, warmup = 2, refine = 1;
  int keyframe_slots = omnipose::KeyframeOptions{}.slots;
  double readout = 0.0, gyro_hz = 0.0;
  double translation_shrinkage = omnipose::MotionFit::Options{}.translation_shrinkage;
  double planar_motion_deg = omnipose::MotionFit::Options{}.planar_motion_deg;
  bool odometry = false, no_moving_content = false, no_ring_consensus = false,
       noise_weighting = false, vertical_scale = false;
  std::string wisdom, save, load;
};

constexpr const char* kUsage =
    "usage: omnipose-bench-instructions [--threads N] [--frames K] [--warmup W]\n"
    "                                   [--refine R] [--wisdom FILE] [--save DIR | --load DIR]\n"
    "                                   [--odometry [--readout S [--gyro HZ]] [--keyframe-slots N]]\n"
    "                                   [--no-moving-content] [--no-ring-consensus]\n"
    "                                   [--noise-weighting] [--vertical-scale]\n"
    "                                   [--translation-shrinkage K]\n"
    "                                   [--planar-motion-deg D]";

constexpr const char* kDescription =
    "Per-frame instruction counts of the pipeline, for valgrind --tool=callgrind\n"
    "--collect-atstart=no (only the measured frames are collected). Prints frames, threads,\n"
    "refine, ok and ms_per_frame (wall time, milliseconds).";

void addOptions(CLI::App& app, Args& a) {
  app.add_option("--threads", a.threads, "pipeline worker threads")->type_name("N")->capture_default_str();
  app.add_option("--frames", a.frames, "measured frames")->type_name("K")->capture_default_str();
  app.add_option("--warmup", a.warmup, "frames processed before measuring")
      ->type_name("W")
      ->capture_default_str();
  app.add_option("--refine", a.refine, "refinement iterations per frame")
      ->type_name("R")
      ->capture_default_str();
  app.add_option("--wisdom", a.wisdom, "FFTW wisdom file")->type_name("FILE");
  auto* save_opt = app.add_option("--save", a.save, "write the two rendered frames to DIR/a.png, "
                                                    "DIR/b.png")->type_name("DIR");
  app.add_option("--load", a.load, "read the two frames from DIR/a.png, DIR/b.png instead of "
                                   "rendering them")
      ->type_name("DIR")
      ->excludes(save_opt);
  auto* odometry_opt =
      app.add_flag("--odometry", a.odometry, "process with Odometry, frames stamped at 30 fps");
  auto* readout_opt =
      app.add_option("--readout", a.readout, "rolling shutter readout of the calibration, seconds")
          ->type_name("S")
          ->needs(odometry_opt)
          ->check(CLI::Range(-omnipose::SensorTiming::kMaxReadoutS,
                             omnipose::SensorTiming::kMaxReadoutS));
  app.add_option("--gyro", a.gyro_hz, "a gyro sampled at HZ (the rows' rotations from it)")
      ->type_name("HZ")
      ->needs(readout_opt)
      ->check(CLI::Range(10.0, 10000.0));
  app.add_option("--keyframe-slots", a.keyframe_slots,
                 "Odometry's keyframes.slots (0: frame-to-frame chaining)")
      ->type_name("N")
      ->needs(odometry_opt)
      ->check(CLI::Range(0, omnipose::WindowRegistration::kMaxKeyframeSlots))
      ->capture_default_str();
  app.add_flag("--no-moving-content", a.no_moving_content,
               "without the refinement pass's moving-content check "
               "(PipelineOptions::moving_content)");
  app.add_flag("--no-ring-consensus", a.no_ring_consensus,
               "without the fit's ring consensus (MotionFit::Options::ring_consensus)");
  app.add_flag("--noise-weighting", a.noise_weighting,
               "with the registration's signal-to-noise weighting "
               "(WindowRegistration::Options::noise_weighting)");
  app.add_flag("--vertical-scale", a.vertical_scale,
               "with the fit's scale equations from each window's vertical scale "
               "(MotionFit::Options::vertical_scale)");
  app.add_option("--translation-shrinkage", a.translation_shrinkage,
                 "the fit's MotionFit::Options::translation_shrinkage (0: off)")
      ->type_name("K")
      ->check(CLI::Range(0.0, 100.0))
      ->capture_default_str();
  app.add_option("--planar-motion-deg", a.planar_motion_deg,
                 "the fit's MotionFit::Options::planar_motion_deg, degrees (0: tau_z free)")
      ->type_name("D")
      ->check(CLI::Range(0.0, 45.0))
      ->capture_default_str();
}

/// The benchmark's two frames: read from --load, or rendered (3 degrees of roll + yaw apart)
/// and, with --save, written. Throws std::runtime_error when they cannot be read or written.
std::array<cv::Mat, 2> benchmarkFrames(const Args& a) {
  std::array<cv::Mat, 2> f;
  if (!a.load.empty()) {
    f[0] = cv::imread(a.load + "/a.png", cv::IMREAD_GRAYSCALE);
    f[1] = cv::imread(a.load + "/b.png", cv::IMREAD_GRAYSCALE);
    if (f[0].empty() || f[1].empty())
      throw std::runtime_error(a.load + "/a.png, b.png: cannot read");
    return f;
  }
  const auto photo =
      std::filesystem::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg";
  omnipose::synth::Renderer renderer(
      omnipose::synth::Scene::load(photo, omnipose::synth::SceneKind::kSphere),
      omnipose::Calibration{});
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = omnipose::rotationFromVector(Eigen::Vector3d(0.03, 0.0, 0.04));
  renderer.render(Eigen::Isometry3d::Identity()).convertTo(f[0], CV_8U);
  renderer.render(T).convertTo(f[1], CV_8U);
  if (!a.save.empty() && !(cv::imwrite(a.save + "/a.png", f[0]) && cv::imwrite(a.save + "/b.png", f[1])))
    throw std::runtime_error(a.save + "/a.png, b.png: cannot write");
  return f;
}

/// Processes --warmup frames, then --frames frames counted and timed; prints the figures.
/// Exit code 0 when every frame was estimated.
int run(const Args& a) {
  cv::setNumThreads(1);
  const std::array<cv::Mat, 2> f = benchmarkFrames(a);
  omnipose::PipelineOptions options;
  options.threads = a.threads;
  options.refine_iterations = a.refine;
  options.moving_content = !a.no_moving_content;
  options.fit.ring_consensus = !a.no_ring_consensus;
  options.fit.translation_shrinkage = a.translation_shrinkage;
  options.fit.planar_motion_deg = a.planar_motion_deg;
  options.registration.noise_weighting = a.noise_weighting;
  options.fit.vertical_scale = a.vertical_scale;
  options.fftw_wisdom = a.wisdom;
  omnipose::Calibration calibration;
  calibration.sensor.readout_s = a.readout;
  if (a.gyro_hz > 0.0) calibration.imu = omnipose::ImuCalibration{};
  std::optional<omnipose::Pipeline> pipeline;
  std::optional<omnipose::Odometry> odometer;
  if (a.odometry) {
    omnipose::OdometryOptions odometry_options;
    odometry_options.pipeline = options;
    odometry_options.keyframes.slots = a.keyframe_slots;
    odometer.emplace(calibration, odometry_options);
  } else {
    pipeline.emplace(calibration, options);
  }
  int n = 0, ok = 0;
  // The gyro's samples up to each frame's last row (a constant turn: its values change no
  // instruction count), given before the frame.
  std::vector<omnipose::GyroSample> samples;
  double t_gyro = -0.05;
  // One frame (the frames alternate); true when it was estimated.
  const auto process = [&] {
    const cv::Mat& frame = f[n % 2];
    const omnipose::FrameStamp stamp{.time_s = n / 30.0, .sequence = n};
    ++n;
    if (pipeline) return pipeline->process(frame).has_value();
    if (a.gyro_hz > 0.0) {
      samples.clear();
      for (; t_gyro <= stamp.time_s + std::abs(a.readout) + 0.01; t_gyro += 1.0 / a.gyro_hz)
        samples.push_back({t_gyro, Eigen::Vector3d(0.0, 0.0, 1.2)});
      odometer->addGyro(samples);
    }
    return odometer->process(frame, stamp).has_value();
  };
  for (int i = 0; i < a.warmup; ++i) ok += process();
  OMNIPOSE_TOGGLE_COLLECT();
  const auto start = std::chrono::steady_clock::now();
  for (int i = 0; i < a.frames; ++i) ok += process();
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  OMNIPOSE_TOGGLE_COLLECT();
  std::printf("frames=%d threads=%d refine=%d odometry=%d readout_s=%g gyro_hz=%g ok=%d "
              "ms_per_frame=%.3f\n",
              a.frames, pipeline ? pipeline->threads() : a.threads, a.refine, a.odometry ? 1 : 0,
              a.readout, a.gyro_hz, ok, 1e3 * seconds / std::max(a.frames, 1));
  if (odometer && a.gyro_hz > 0.0 && odometer->gyroCounters().frames_with_gyro == 0) {
    std::fprintf(stderr, "no frame used the gyro\n");
    return 1;
  }
  return ok == a.warmup + a.frames ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  omnipose::tools::quietOpenCvWarnings();
  return omnipose::tools::runMain<Args>(
      argc, argv, {"omnipose-bench-instructions", kUsage, kDescription}, addOptions,
      [](auto&, const Args& args) { return run(args); });
}
