#include "daemon/config.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <initializer_list>
#include <numbers>
#include <string>

#include "omnipose/calibration.hpp"
#include "runtime/worker_pool.hpp"

using ::testing::HasSubstr;
using ::testing::Not;

namespace omnipose {
namespace {

/// The smallest valid daemon.yaml: a file source and a calibration.
const std::string kFileSource = "source: {type: file, path: run1}\ncalibration: cal.yaml\n";

/// kFileSource with `extra` appended, parsed as /etc/omnipose/d.yaml.
DaemonConfig parseWith(const std::string& extra) {
  return DaemonConfig::parse(kFileSource + extra, "d.yaml", "/etc/omnipose");
}

/// Parses `text` and returns the problems (empty when valid).
std::vector<std::string> problemsOf(const std::string& text) {
  try {
    DaemonConfig::parse(text, "daemon.yaml", "/tmp");
  } catch (const ConfigError& e) {
    return e.problems();
  }
  return {};
}

bool mentions(const std::vector<std::string>& problems, const std::string& needle) {
  for (const auto& p : problems)
    if (p.find(needle) != std::string::npos) return true;
  return false;
}

/// A boolean `pipeline` key: `get` reads `default_value` without it, the other value with it
/// set (and describe() shows it), and `bad` (not a boolean) is a problem naming the key.
void expectBooleanPipelineKey(const std::string& key, bool default_value,
                              bool (*get)(const DaemonConfig&), const std::string& bad) {
  SCOPED_TRACE(key);
  EXPECT_EQ(get(parseWith("")), default_value);
  const std::string other = default_value ? "false" : "true";
  const DaemonConfig set = parseWith("pipeline: {" + key + ": " + other + "}\n");
  EXPECT_EQ(get(set), !default_value);
  EXPECT_THAT(set.describe(), HasSubstr(key + ": " + other));
  EXPECT_TRUE(mentions(problemsOf(kFileSource + "pipeline: {" + key + ": " + bad + "}\n"),
                       "pipeline." + key));
}

/// A numeric pipeline key whose 0 turns its mechanism off: its default, 0 parsed and
/// described, and every value in `bad` refused with a problem naming pipeline.KEY.
void expectNumericPipelineKey(const std::string& key, double default_value,
                              double (*get)(const DaemonConfig&),
                              std::initializer_list<const char*> bad) {
  SCOPED_TRACE(key);
  EXPECT_DOUBLE_EQ(get(parseWith("")), default_value);
  const DaemonConfig off = parseWith("pipeline: {" + key + ": 0}\n");
  EXPECT_DOUBLE_EQ(get(off), 0.0);
  EXPECT_THAT(off.describe(), HasSubstr(key + ": 0"));
  for (const char* value : bad)
    EXPECT_TRUE(mentions(problemsOf(kFileSource + "pipeline: {" + key + ": " + value + "}\n"),
                         "pipeline." + key))
        << value;
}

TEST(DaemonConfig, DefaultsAreThePapersValues) {
  const DaemonConfig c = parseWith("");
  EXPECT_EQ(c.source.type, SourceConfig::Type::kFile);
  EXPECT_EQ(c.source.path, std::filesystem::path("/etc/omnipose/run1"));
  EXPECT_EQ(c.calibration, std::filesystem::path("/etc/omnipose/cal.yaml"));
  EXPECT_TRUE(c.source.realtime);
  EXPECT_EQ(c.pipeline.registration.window, 110);
  EXPECT_EQ(c.pipeline.registration.step, 20);
  EXPECT_DOUBLE_EQ(c.pipeline.fit.huber_delta_px, 2.0);
  EXPECT_EQ(c.pipeline.fit.median, 5);
  EXPECT_EQ(c.lcm.pose_channel, "OMNI_POSE");
  EXPECT_EQ(c.lcm.status_channel, "OMNI_STATUS");
  EXPECT_EQ(c.lcm.fit_channel, "");
  EXPECT_DOUBLE_EQ(c.lcm.status_hz, 1.0);
  EXPECT_THAT(c.describe(), HasSubstr("window: 110"));
}

TEST(DaemonConfig, EveryProblemIsReportedAtOnce) {
  const std::string text = R"(source:
  type: usb
  speed: 3
input: fisheye
pipeline:
  window: 110
  step: 0
  colour: blue
lcm:
  status_hz: -1
bogus: 1
)";
  try {
    DaemonConfig::parse(text, "daemon.yaml", "/tmp");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    const std::string what = e.what();
    for (const char* key : {"source.type", "source.speed: unknown key", "input", "pipeline.colour",
                            "lcm.status_hz", "bogus: unknown key", "calibration: missing",
                            "daemon.yaml: pipeline.step: 0 is outside [1, 4096] pixels"}) {
      EXPECT_THAT(what, HasSubstr(key)) << key << " not in:\n" << what;
    }
    EXPECT_GE(e.problems().size(), 8u) << what;
    // Every problem is named by a key the user can write, once.
    int step_problems = 0;
    for (const auto& p : e.problems()) {
      EXPECT_THAT(p, Not(HasSubstr("registration")));
      EXPECT_THAT(p, Not(HasSubstr("built-in")));
      step_problems += p.find("pipeline.step") != std::string::npos;
    }
    EXPECT_EQ(step_problems, 1) << what;
  }
}

TEST(DaemonConfig, PipelineThreads) {
  EXPECT_EQ(parseWith("").pipeline.threads, 0);  // default: all online cores
  EXPECT_EQ(DaemonConfig{}.odometry().pipeline.threads, 0) << "the replay without a daemon.yaml";
  const int cores = runtime::WorkerPool::onlineCores();
  const DaemonConfig c = parseWith("pipeline: {threads: 1}\n");
  EXPECT_EQ(c.pipeline.threads, 1);
  EXPECT_THAT(c.describe(), HasSubstr("threads: 1"));
  EXPECT_TRUE(c.warnings.empty());
  EXPECT_TRUE(mentions(problemsOf(kFileSource + "pipeline: {threads: -3}\n"), "pipeline.threads"));
  // More than the cores this process may use: clamped, with a warning naming the key.
  const DaemonConfig many = parseWith("pipeline: {threads: " + std::to_string(cores + 1) + "}\n");
  EXPECT_EQ(many.pipeline.threads, cores);
  ASSERT_EQ(many.warnings.size(), 1u);
  EXPECT_THAT(many.warnings[0],
              HasSubstr("d.yaml: pipeline.threads: " + std::to_string(cores + 1) +
                        " is more than the " + std::to_string(cores) + " cores"));
}

TEST(DaemonConfig, MovingContentCheck) {
  expectBooleanPipelineKey(
      "moving_content", true, [](const DaemonConfig& c) { return c.pipeline.moving_content; },
      "sometimes");
}

TEST(DaemonConfig, YawCaptureTime) {
  expectBooleanPipelineKey(
      "yaw_capture_time", true, [](const DaemonConfig& c) { return c.pipeline.yaw_capture_time; },
      "gyro");
}

TEST(DaemonConfig, GyroFusion) {
  expectBooleanPipelineKey(
      "gyro_fusion", true, [](const DaemonConfig& c) { return c.pipeline.gyro_fusion; }, "always");
}

TEST(DaemonConfig, NoiseWeighting) {
  expectBooleanPipelineKey(
      "noise_weighting", false,
      [](const DaemonConfig& c) { return c.pipeline.registration.noise_weighting; }, "2");
}

TEST(DaemonConfig, CubicWindowSampling) {
  expectBooleanPipelineKey(
      "cubic_window_sampling", false,
      [](const DaemonConfig& c) { return c.pipeline.registration.cubic_sampling; }, "cubic");
}

TEST(DaemonConfig, DewarpByFit) {
  expectBooleanPipelineKey(
      "dewarp_by_fit", false, [](const DaemonConfig& c) { return c.pipeline.dewarp_by_fit; },
      "predicted");
}

TEST(DaemonConfig, PlaneDepthPrior) {
  expectBooleanPipelineKey(
      "plane_depth_prior", true,
      [](const DaemonConfig& c) { return c.pipeline.fit.plane_depth_prior; }, "walls");
}

TEST(DaemonConfig, RingConsensus) {
  expectBooleanPipelineKey(
      "ring_consensus", true,
      [](const DaemonConfig& c) { return c.pipeline.fit.ring_consensus; }, "people");
}

TEST(DaemonConfig, VerticalScale) {
  expectBooleanPipelineKey(
      "vertical_scale", false,
      [](const DaemonConfig& c) { return c.pipeline.fit.vertical_scale; }, "vertical");
}

TEST(DaemonConfig, TranslationShrinkage) {
  expectNumericPipelineKey(
      "translation_shrinkage", 3.0,
      [](const DaemonConfig& c) { return c.pipeline.fit.translation_shrinkage; },
      {"-1", "101", "much"});
}

TEST(DaemonConfig, PlanarMotion) {
  expectNumericPipelineKey(
      "planar_motion_deg", 10.0,
      [](const DaemonConfig& c) { return c.pipeline.fit.planar_motion_deg; },
      {"-1", "46", "flat"});
}

TEST(DaemonConfig, PanoramaPicturesAreOffUnlessAChannelIsNamed) {
  const DaemonConfig defaults = parseWith("");
  EXPECT_EQ(defaults.lcm.panorama_channel, "");
  EXPECT_DOUBLE_EQ(defaults.lcm.panorama_hz, 2.0);
  EXPECT_EQ(defaults.lcm.panorama_width, 640);
  const DaemonConfig set =
      parseWith("lcm: {panorama_channel: OMNI_PANORAMA, panorama_hz: 5, panorama_width: 320}\n");
  EXPECT_EQ(set.lcm.panorama_channel, "OMNI_PANORAMA");
  EXPECT_DOUBLE_EQ(set.lcm.panorama_hz, 5.0);
  EXPECT_EQ(set.lcm.panorama_width, 320);
  EXPECT_THAT(set.describe(), HasSubstr("panorama_channel: \"OMNI_PANORAMA\""));
  EXPECT_TRUE(mentions(problemsOf(kFileSource + "lcm: {panorama_width: wide}\n"),
                       "lcm.panorama_width"));
}

TEST(DaemonConfig, KeyframesSection) {
  const DaemonConfig defaults = parseWith("");
  EXPECT_EQ(defaults.keyframes.slots, 4) << "on by default";
  EXPECT_EQ(defaults.odometry().keyframes.slots, 4);
  EXPECT_DOUBLE_EQ(defaults.keyframes.anchor_gain, 0.1);
  const DaemonConfig c = parseWith(
      "keyframes: {slots: 0, max_translation: 0.05, max_tilt_deg: 3, min_ring_peak: 0.1, "
      "anchor_gain: 0.5, anchor_interval: 3}\n");
  EXPECT_EQ(c.keyframes.slots, 0);
  EXPECT_DOUBLE_EQ(c.keyframes.anchor_gain, 0.5);
  EXPECT_EQ(c.keyframes.anchor_interval, 3);
  EXPECT_DOUBLE_EQ(c.keyframes.max_translation, 0.05);
  EXPECT_NEAR(c.keyframes.max_tilt_rad, 3 * std::numbers::pi / 180.0, 1e-12);
  EXPECT_DOUBLE_EQ(c.keyframes.min_ring_peak, 0.1);
  EXPECT_THAT(c.describe(), HasSubstr("slots: 0"));
  EXPECT_THAT(c.describe(), HasSubstr("anchor_gain: 0.5"));
  const auto problems = problemsOf(
      kFileSource +
      "keyframes: {slots: 17, max_tilt_deg: 40, anchor_gain: 1.5, anchor_interval: 0, cadence: 3}\n");
  EXPECT_TRUE(mentions(problems, "keyframes.slots"));
  EXPECT_TRUE(mentions(problems, "keyframes.max_tilt_deg"));
  EXPECT_TRUE(mentions(problems, "keyframes.anchor_gain"));
  EXPECT_TRUE(mentions(problems, "keyframes.anchor_interval"));
  EXPECT_TRUE(mentions(problems, "cadence"));
}

TEST(DaemonConfig, LoopClosureSection) {
  const DaemonConfig defaults = parseWith("");
  EXPECT_TRUE(defaults.loop_closure.enabled) << "on by default";
  EXPECT_TRUE(defaults.odometry().loop_closure.enabled);
  EXPECT_EQ(defaults.loop_closure.max_places, 128);
  const DaemonConfig c = parseWith(
      "loop_closure: {enabled: false, max_places: 64, place_spacing: 0.2, search_radius: 0.5, "
      "min_similarity: 0.8, max_correction_deg: 3, check_interval: 10, confirmations: 3, "
      "max_turn_rate_deg_s: 10}\n");
  EXPECT_FALSE(c.odometry().loop_closure.enabled);
  EXPECT_EQ(c.loop_closure.max_places, 64);
  EXPECT_DOUBLE_EQ(c.loop_closure.place_spacing, 0.2);
  EXPECT_DOUBLE_EQ(c.loop_closure.search_radius, 0.5);
  EXPECT_DOUBLE_EQ(c.loop_closure.min_similarity, 0.8);
  EXPECT_NEAR(c.loop_closure.max_correction_rad, 3 * std::numbers::pi / 180.0, 1e-12);
  EXPECT_EQ(c.loop_closure.check_interval, 10);
  EXPECT_EQ(c.loop_closure.confirmations, 3);
  EXPECT_NEAR(c.loop_closure.max_turn_rate_rad_s, 10 * std::numbers::pi / 180.0, 1e-12);
  EXPECT_THAT(c.describe(), HasSubstr("loop_closure:\n  enabled: false\n  max_places: 64"));
  const auto problems = problemsOf(
      kFileSource +
      "loop_closure: {max_places: 1, place_spacing: 0, search_radius: 20, min_similarity: 1, "
      "max_correction_deg: 45, check_interval: 0, confirmations: 11, max_turn_rate_deg_s: -1, "
      "memory: x}\n");
  for (const char* key : {"loop_closure.max_places", "loop_closure.place_spacing",
                          "loop_closure.search_radius", "loop_closure.min_similarity",
                          "loop_closure.max_correction_deg", "loop_closure.check_interval",
                          "loop_closure.confirmations", "loop_closure.max_turn_rate_deg_s",
                          "memory"})
    EXPECT_TRUE(mentions(problems, key)) << key;
}

TEST(DaemonConfig, TheMapFileIsResolvedAgainstTheConfigFolderAndItsIntervalChecked) {
  const DaemonConfig defaults = parseWith("");
  EXPECT_TRUE(defaults.map_file.path.empty()) << "no map file by default";
  EXPECT_DOUBLE_EQ(defaults.map_file.save_interval_s, 60.0);
  const DaemonConfig c = DaemonConfig::parse(
      kFileSource + "loop_closure: {map_file: maps/robot.map, save_interval_s: 0}\n",
      "/etc/omnipose/daemon.yaml", "/etc/omnipose");
  EXPECT_EQ(c.map_file.path, std::filesystem::path("/etc/omnipose/maps/robot.map"));
  EXPECT_DOUBLE_EQ(c.map_file.save_interval_s, 0.0) << "0: only at shutdown";
  EXPECT_THAT(c.describe(), HasSubstr("map_file: \"/etc/omnipose/maps/robot.map\"\n  save_interval_s: 0"));
  EXPECT_EQ(parseWith("loop_closure: {map_file: /var/lib/omnipose/robot.map}\n").map_file.path,
            std::filesystem::path("/var/lib/omnipose/robot.map"));
  EXPECT_TRUE(mentions(problemsOf(kFileSource + "loop_closure: {save_interval_s: -1}\n"),
                       "loop_closure.save_interval_s: -1"));
  EXPECT_TRUE(mentions(problemsOf(kFileSource + "loop_closure: {save_interval_s: .nan}\n"),
                       "loop_closure.save_interval_s"));
  EXPECT_TRUE(mentions(
      problemsOf(kFileSource + "loop_closure: {enabled: false, map_file: robot.map}\n"),
      "loop_closure.map_file: set while loop_closure.enabled is false"));
}

TEST(DaemonConfig, SchedulingSection) {
  const DaemonConfig defaults = parseWith("");
  EXPECT_EQ(defaults.scheduling.fifo_priority, 0) << "normal scheduling by default";
  EXPECT_TRUE(defaults.scheduling.cpus.empty()) << "every CPU by default";
  EXPECT_THAT(defaults.describe(), HasSubstr("scheduling:\n  fifo_priority: 0\n  cpus: []"));
  const DaemonConfig c = parseWith("scheduling: {fifo_priority: 20, cpus: [0, 1]}\n");
  EXPECT_EQ(c.scheduling.fifo_priority, 20);
  EXPECT_EQ(c.scheduling.cpus, (std::vector<int>{0, 1}));
  EXPECT_THAT(c.describe(), HasSubstr("cpus: [0, 1]"));
  // pipeline.threads above the CPUs listed is clamped to them.
  const DaemonConfig one = parseWith("scheduling: {cpus: [0]}\npipeline: {threads: 2}\n");
  EXPECT_EQ(one.pipeline.threads, 1);
  EXPECT_EQ(one.warnings.size(), 1u);
  const auto problems = problemsOf(
      kFileSource + "scheduling: {fifo_priority: 100, cpus: [-1, x], policy: rr}\n");
  EXPECT_TRUE(mentions(problems, "scheduling.fifo_priority")) << problems.size();
  EXPECT_TRUE(mentions(problems, "scheduling.cpus: cannot read '[-1, x]' as a list of integers"));
  EXPECT_TRUE(mentions(problems, "scheduling.policy"));
  EXPECT_TRUE(mentions(problemsOf(kFileSource + "scheduling: {cpus: [-2]}\n"),
                       "scheduling.cpus: -2 is not a CPU number"));
  EXPECT_TRUE(mentions(problemsOf(kFileSource + "scheduling: {fifo_priority: -1}\n"),
                       "scheduling.fifo_priority"));
}

TEST(DaemonConfig, ImuSection) {
  const DaemonConfig defaults = parseWith("");
  EXPECT_EQ(defaults.imu.source, ImuConfig::Source::kNone) << "no gyro by default";
  EXPECT_THAT(defaults.describe(), HasSubstr("imu:\n  source: none\n  channel: OMNI_IMU\n  url: \"\""));
  const DaemonConfig c = parseWith("imu: {source: lcm, channel: ROBOT_IMU, url: \"udpm://239.255.76.67:7667\"}\n");
  EXPECT_EQ(c.imu.source, ImuConfig::Source::kLcm);
  EXPECT_EQ(c.imu.channel, "ROBOT_IMU");
  EXPECT_EQ(c.imu.url, "udpm://239.255.76.67:7667");
  EXPECT_THAT(c.describe(), HasSubstr("imu:\n  source: lcm\n  channel: ROBOT_IMU"));
  const auto problems = problemsOf(kFileSource + "imu: {source: spi, rate: 200}\n");
  EXPECT_TRUE(mentions(problems, "imu.source")) << problems.size();
  EXPECT_TRUE(mentions(problems, "imu.rate"));
  EXPECT_TRUE(mentions(problemsOf(kFileSource + "imu: {source: lcm, channel: \"\"}\n"),
                       "imu.channel: must not be empty"));
  // Received on lcm.url unless told otherwise, which cannot be a log the daemon writes.
  EXPECT_TRUE(mentions(
      problemsOf(kFileSource + "lcm: {url: \"file:///tmp/x.lcm?mode=w\"}\nimu: {source: lcm}\n"),
      "imu.url: needed: lcm.url \"file:///tmp/x.lcm?mode=w\" is a log the daemon writes"));
}

TEST(DaemonConfig, ImuSectionWithAnIioGyro) {
  const DaemonConfig c = parseWith("imu: {source: iio, device: bmi160, sampling_hz: 400}\n");
  EXPECT_EQ(c.imu.source, ImuConfig::Source::kIio);
  EXPECT_EQ(c.imu.device, "bmi160");
  EXPECT_DOUBLE_EQ(c.imu.sampling_hz, 400.0);
  EXPECT_THAT(c.describe(), HasSubstr("imu:\n  source: iio\n  channel: OMNI_IMU\n  url: \"\"\n"
                                      "  device: \"bmi160\"\n  sampling_hz: 400\n"));
  EXPECT_EQ(parseWith("imu: {source: iio, device: \"iio:device2\"}\n").imu.sampling_hz, 0.0)
      << "the device's rate is left alone by default";
  // Every problem at once, each named by its key.
  const auto problems = problemsOf(kFileSource + "imu: {source: iio, sampling_hz: -5}\n");
  EXPECT_TRUE(mentions(problems, "imu.device: needed: iio:deviceN"));
  EXPECT_TRUE(mentions(problems, "imu.sampling_hz"));
  EXPECT_TRUE(mentions(problemsOf(kFileSource + "imu: {source: iio, device: /dev/iio:device0}\n"),
                       "imu.device: \"/dev/iio:device0\" is a path"));
  EXPECT_TRUE(mentions(problemsOf(kFileSource + "imu: {source: iio, device: bmi160, sampling_hz: 1e6}\n"),
                       "imu.sampling_hz"));
  EXPECT_TRUE(mentions(problemsOf(kFileSource + "imu: {source: iio, device: bmi160, rate: 1}\n"),
                       "imu.rate"));
}

TEST(DaemonConfig, ReplayUseNeedsNoSource) {
  const DaemonConfig c = DaemonConfig::parse("input: panorama\npipeline: {refine_iterations: 2}\n",
                                             "r.yaml", "/tmp", DaemonConfig::Use::kReplay);
  EXPECT_EQ(c.pipeline.unwrap.input, InputKind::kPanorama);
  EXPECT_EQ(c.pipeline.refine_iterations, 2);
  EXPECT_THROW(DaemonConfig::parse("input: panorama\n", "r.yaml", "/tmp"), ConfigError);
}

TEST(DaemonConfig, MissingFileAndBrokenYamlAreClear) {
  EXPECT_THROW(DaemonConfig::load("/nonexistent/daemon.yaml"), ConfigError);
  try {
    DaemonConfig::parse("source: [unclosed\n", "x.yaml", "/tmp");
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_THAT(e.what(), HasSubstr("x.yaml: not valid YAML"));
  }
}

std::string joined(const std::vector<std::string>& problems) {
  std::string all;
  for (const auto& p : problems) all += p + "\n";
  return all;
}

TEST(DaemonConfig, EveryNumberMustBeFiniteAndInItsRangeNamingFileAndField) {
  const std::string& head = kFileSource;
  struct Case {
    std::string yaml;
    std::string field;
    std::string says;
  };
  const std::vector<Case> cases = {
      {"source: {type: v4l2, width: 100000}\ncalibration: c.yaml\n", "daemon.yaml: source.width",
       "[1, 16384]"},
      {"source: {type: v4l2, height: -4}\ncalibration: c.yaml\n", "daemon.yaml: source.height",
       "[1, 16384]"},
      {"source: {type: v4l2, fps: .nan}\ncalibration: c.yaml\n", "daemon.yaml: source.fps",
       "finite"},
      {"source: {type: v4l2, fps: .inf}\ncalibration: c.yaml\n", "daemon.yaml: source.fps",
       "finite"},
      {head + "pipeline: {window: 100000}\n", "daemon.yaml: pipeline.window", "[16, 512]"},
      {head + "pipeline: {step: 1000000000}\n", "daemon.yaml: pipeline.step", "[1, 4096]"},
      {head + "pipeline: {huber_delta_px: .inf}\n", "daemon.yaml: pipeline.huber_delta_px",
       "finite"},
      {head + "pipeline: {huber_delta_px: 1e300}\n", "daemon.yaml: pipeline.huber_delta_px",
       "(0, 100]"},
      {head + "pipeline: {median: 99}\n", "daemon.yaml: pipeline.median", "[0, 15]"},
      {head + "pipeline: {refine_iterations: -1}\n", "daemon.yaml: pipeline.refine_iterations",
       "[0, 5]"},
      {head + "pipeline: {min_confidence: .nan}\n", "daemon.yaml: pipeline.min_confidence",
       "finite"},
      {head + "pipeline: {inlier_sigmas: -.inf}\n", "daemon.yaml: pipeline.inlier_sigmas",
       "finite"},
      {head + "lcm: {status_hz: .nan}\n", "daemon.yaml: lcm.status_hz", "finite"},
      {head + "lcm: {panorama_hz: 0}\n", "daemon.yaml: lcm.panorama_hz", "(0, 30]"},
      {head + "lcm: {panorama_hz: .inf}\n", "daemon.yaml: lcm.panorama_hz", "finite"},
      {head + "lcm: {panorama_width: 32}\n", "daemon.yaml: lcm.panorama_width", "[64, 4096]"},
      {head + "lcm: {status_hz: 1000}\n", "daemon.yaml: lcm.status_hz", "(0, 100]"},
      {head + "pipeline: {window: 3000000000}\n", "daemon.yaml: pipeline.window", "an integer"},
      {head + "pipeline: {step: 2.5}\n", "daemon.yaml: pipeline.step", "an integer"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.yaml);
    const auto problems = problemsOf(c.yaml);
    ASSERT_FALSE(problems.empty());
    bool found = false;
    for (const auto& p : problems)
      found |= p.rfind(c.field, 0) == 0 && p.find(c.says) != std::string::npos;
    EXPECT_TRUE(found) << "expected '" << c.field << "' ... '" << c.says << "' in:\n"
                       << joined(problems);
  }
  // The upper bounds themselves are accepted.
  EXPECT_TRUE(problemsOf("source: {type: v4l2, width: 16384, height: 16384, fps: 1000}\n"
                         "calibration: c.yaml\n")
                  .empty());
}

TEST(DaemonConfig, OddYamlShapesAreProblemsNotExceptions) {
  // Non-scalar keys, a sequence where a map belongs, a map where a number belongs.
  for (const std::string& text :
       {std::string("? [a, b]\n: 1\nsource: {type: file, path: x}\ncalibration: c\n"),
        std::string("source: [1, 2]\ncalibration: c\n"),
        std::string("source: {type: file, path: x}\ncalibration: {a: 1}\n"),
        std::string("source: {type: file, path: x, fps: {a: 1}}\ncalibration: c\n"),
        std::string("- 1\n- 2\n"), std::string("just text\n")}) {
    SCOPED_TRACE(text);
    try {
      DaemonConfig::parse(text, "daemon.yaml", "/tmp");
      ADD_FAILURE() << "accepted";
    } catch (const ConfigError& e) {
      EXPECT_FALSE(e.problems().empty());
      EXPECT_THAT(e.what(), HasSubstr("daemon.yaml"));
    }
  }
  EXPECT_TRUE(mentions(problemsOf("? [a, b]\n: 1\nsource: {type: file, path: x}\ncalibration: c\n"),
                       "keys must be plain names"));
}

TEST(DaemonConfig, PipelineSizesAreCheckedAgainstTheCalibrationBeforeAnythingIsAllocated) {
  Calibration cal;  // 1100 x 110 panorama
  const auto c = DaemonConfig::parse("source: {type: file, path: r}\ncalibration: c.yaml\n",
                                     "/etc/d.yaml", "/etc");
  EXPECT_EQ(c.origin, "/etc/d.yaml");
  EXPECT_TRUE(c.checkAgainst(cal, c.origin).empty()) << "the paper's setting fits";
  auto tall = c;
  tall.pipeline.registration.window = 200;
  const auto p1 = tall.checkAgainst(cal, tall.origin);
  ASSERT_EQ(p1.size(), 1u);
  EXPECT_THAT(p1[0],
              HasSubstr("/etc/d.yaml: pipeline.window: 200 is larger than the "
                        "panorama (1100 x 110"));
  auto dense = c;
  dense.pipeline.registration.step = 1;
  dense.pipeline.registration.window = 110;
  cal.panorama.width = 8000;
  const auto p2 = dense.checkAgainst(cal, dense.origin);
  ASSERT_EQ(p2.size(), 1u);
  EXPECT_THAT(p2[0], HasSubstr("/etc/d.yaml: pipeline.step: 1 gives 8000 windows"));
  EXPECT_THAT(p2[0], HasSubstr("largest supported is 16777216"));
}

int lineCount(const std::string& text) {
  return static_cast<int>(std::count(text.begin(), text.end(), '\n')) + 1;
}

/// what() of parsing `text` as daemon.yaml ("" when valid).
std::string whatOf(const std::string& text) {
  try {
    DaemonConfig::parse(text, "daemon.yaml", "/tmp");
  } catch (const ConfigError& e) {
    return e.what();
  }
  return "";
}

TEST(DaemonConfig, DuplicateKeysAtEveryLevelAreProblemsNamingBothLines) {
  const std::string& head = kFileSource;
  const std::string text = head +
                           "pipeline:\n"
                           "  window: 110\n"
                           "  step: 20\n"
                           "  window: abc\n"
                           "lcm: {status_hz: 1, status_hz: [1, 2]}\n"
                           "calibration: other.yaml\n";
  const auto problems = problemsOf(text);
  EXPECT_TRUE(mentions(problems, "daemon.yaml: pipeline.window: given twice, lines 4 and 6"));
  EXPECT_TRUE(mentions(problems, "daemon.yaml: lcm.status_hz: given twice, lines 7 and 7"));
  EXPECT_TRUE(mentions(problems, "daemon.yaml: calibration: given twice, lines 2 and 8"));
  EXPECT_EQ(problems.size(), 3u);
  EXPECT_TRUE(problemsOf(head + "pipeline: {window: 110}\nlcm: {status_hz: 1}\n").empty());
}

TEST(DaemonConfig, AMultiMegabyteValueGivesAShortMessage) {
  const std::string big(8u << 20, 'p');  // 2048 times the bound
  const std::string what = whatOf("source: {type: file, path: " + big + "}\ncalibration: c.yaml\n");
  EXPECT_LT(what.size(), 1024u) << what.substr(0, 300);
  EXPECT_THAT(what,
              HasSubstr("source.path: '" + std::string(60, 'p') +
                        "... (8388608 bytes)' is longer than 4096 bytes"))
      << what.substr(0, 300);
  // A long number and a long (explicit) key are echoed short too.
  const std::string mb(1u << 20, 'p');
  for (const std::string& text :
       {"source: {type: file, path: run1}\ncalibration: c.yaml\npipeline: {window: " + mb + "}\n",
        "source: {type: file, path: run1}\ncalibration: c.yaml\n? " + mb + "\n: 1\n"}) {
    const std::string short_what = whatOf(text);
    SCOPED_TRACE(short_what.substr(0, 300));
    EXPECT_LT(short_what.size(), 1024u);
    EXPECT_THAT(short_what, HasSubstr(std::string(60, 'p').append("... (1048576 bytes)")));
  }
}

TEST(DaemonConfig, ControlCharactersInKeysAndValuesAreEscaped) {
  const std::string what =
      whatOf("source: {type: \"fi\\0le\", path: run1}\ncalibration: c.yaml\n\"bo\\0gus\\r\": 1\n");
  EXPECT_EQ(std::string(what.c_str()), what) << "a NUL in what()";
  EXPECT_THAT(what, HasSubstr("source.type: 'fi\\0le' is not file, v4l2 or libcamera"));
  EXPECT_THAT(what, HasSubstr("bo\\0gus\\r: unknown key"));
}

TEST(DaemonConfig, AtMostTwentyProblemsAreListed) {
  std::string text = "source: {type: file, path: run1}\ncalibration: c.yaml\n";
  for (int i = 0; i < 25; ++i) text += "bogus" + std::to_string(i) + ": 1\n";
  EXPECT_EQ(problemsOf(text).size(), 25u);
  const std::string what = whatOf(text);
  EXPECT_EQ(lineCount(what), 22) << what;
  EXPECT_THAT(what, HasSubstr("\n  and 5 more"));
}

}  // namespace
}  // namespace omnipose
