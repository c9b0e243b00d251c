#include "omnipose/config.hpp"

#include <gtest/gtest.h>

namespace omnipose {
namespace {

TEST(DaemonConfig, DefaultsAreThePapersValues) {
  const DaemonConfig c = DaemonConfig::parse(
      "source: {type: file, path: run1}\ncalibration: cal.yaml\n", "d.yaml", "/etc/omnipose");
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
  EXPECT_NE(c.describe().find("window: 110"), std::string::npos);
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
                            "registration: step"}) {
      EXPECT_NE(what.find(key), std::string::npos) << key << " not in:\n" << what;
    }
    EXPECT_GE(e.problems().size(), 8u) << what;
  }
}

TEST(DaemonConfig, PipelineThreads) {
  const auto parse = [](const std::string& pipeline) {
    return DaemonConfig::parse("source: {type: file, path: run1}\ncalibration: cal.yaml\n" + pipeline,
                               "d.yaml", "/etc/omnipose");
  };
  EXPECT_EQ(parse("").pipeline.threads, 0);  // default: all online cores
  const DaemonConfig c = parse("pipeline: {threads: 2}\n");
  EXPECT_EQ(c.pipeline.threads, 2);
  EXPECT_NE(c.describe().find("threads: 2"), std::string::npos);
  try {
    parse("pipeline: {threads: -3}\n");
    FAIL() << "expected ConfigError";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("pipeline.threads"), std::string::npos) << e.what();
  }
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
    EXPECT_NE(std::string(e.what()).find("x.yaml: not valid YAML"), std::string::npos);
  }
}

}  // namespace
}  // namespace omnipose
