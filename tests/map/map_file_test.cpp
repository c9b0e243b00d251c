// The map on disk (src/map/map_file.hpp): a saved map comes back place for place and edge for
// edge, renumbered with node 0 first; a file that is not a usable map (missing, foreign, cut
// short, damaged, another version, another panorama size or lens, too many places, not a
// regular file) is refused naming the file and why, leaving nothing loaded; a file that is not
// a map is never overwritten; a second snapshot allocates nothing.
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/stat.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <numbers>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "allocation_counter.hpp"
#include "map/map_file.hpp"
#include "planar_pose.hpp"
#include "test_files.hpp"

namespace omnipose::map {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

const cv::Size kPanorama(220, 22);

/// The default calibration with panoramas of `size` pixels.
Calibration calibrationOf(cv::Size size) {
  Calibration c;
  c.panorama.width = size.width;
  c.panorama.height = size.height;
  c.panorama.horizon_row = (size.height - 1) / 2.0;
  return c;
}
const Calibration kCalibration = calibrationOf(kPanorama);

/// A textured panorama (CV_32FC1), different for every seed.
cv::Mat texture(int seed) {
  cv::Mat out(kPanorama, CV_32FC1);
  cv::RNG rng(static_cast<std::uint64_t>(seed) + 1);
  rng.fill(out, cv::RNG::UNIFORM, 0.0, 255.0);
  return out;
}

/// Six places along a line with a loop edge from the last to the first, then place 3
/// forgotten (its neighbours joined through it): a memory with a hole, as a long run leaves it.
struct Map {
  PlaceMemory memory{8, kPanorama};
  PoseGraph graph{8, 32};
  Map() {
    PlaceSignature signer(kPanorama);
    PlaceSignature::Vector signature;
    for (int i = 0; i < 6; ++i) {
      const int id = graph.addNode(testing::planarPose(0.1 * i, 0.0, 0.01 * i));
      const cv::Mat view = texture(i);
      signer.compute(view, signature);
      memory.store(id, view, signature, 100 + 10 * i, 3.0 + i / 3.0, 0.05 * i);
      if (i > 0) {
        PoseGraph::Edge e;
        e.from = i - 1;
        e.to = i;
        e.relative = testing::planarPose(0.1, 0.0, 0.01);
        e.rotation_sigma = 1e-3;
        e.position_sigma = 0.01;
        EXPECT_TRUE(graph.addEdge(e));
      }
    }
    PoseGraph::Edge loop;
    loop.from = 5;
    loop.to = 0;
    loop.relative = graph.pose(5).inverse() * graph.pose(0);
    loop.rotation_sigma = 2e-3;
    loop.position_sigma = 0.05;
    loop.loop = true;
    EXPECT_TRUE(graph.addEdge(loop));
    memory.touch(1);
    graph.removeNode(3);
    memory.remove(3);
  }
};

/// The snapshot of `map` as the daemon would save it.
MapSnapshot snapshotOf(const Map& map) {
  MapSnapshot snapshot;
  takeSnapshot(map.memory, map.graph, snapshot);
  snapshot.lens = LensGrid::of(kCalibration);  // as Odometry::snapshotMap() does
  return snapshot;
}

TEST(MapFile, ARoundTripKeepsEveryPlaceAndEdge) {
  const testing::TempDir tmp("map");
  const Map map;
  const MapSnapshot saved = snapshotOf(map);
  ASSERT_EQ(saved.place_count, 5);
  ASSERT_TRUE(saveMap(tmp / "map.bin", saved).has_value());

  MapSnapshot loaded;
  const auto ok = loadMap(tmp / "map.bin", kCalibration, 8, loaded);
  ASSERT_TRUE(ok.has_value()) << ok.error().message();
  EXPECT_EQ(loaded.lens.farthestPx(saved.lens), 0.0);
  PlaceMemory memory(8, kPanorama);
  PoseGraph graph(8, 32);
  ASSERT_TRUE(restoreSnapshot(loaded, memory, graph).has_value());
  EXPECT_EQ(memory.size(), 5);
  EXPECT_EQ(graph.nodeCount(), 5);
  EXPECT_EQ(graph.edgeCount(), map.graph.edgeCount());
  EXPECT_EQ(memory.stored(), 6) << "the newest place's serial: places made later come after it";
  // Ids 0, 1, 2, 4, 5 became 0..4, in order: node 0, the gauge, is node 0.
  const int old_id[] = {0, 1, 2, 4, 5};
  for (int id = 0; id < 5; ++id) {
    SCOPED_TRACE(id);
    const Place& a = map.memory[old_id[id]];
    const Place& b = memory[id];
    ASSERT_TRUE(b.valid);
    EXPECT_EQ(b.sequence, a.sequence);
    EXPECT_EQ(b.time_s, a.time_s);
    EXPECT_EQ(b.yaw_rate, a.yaw_rate);
    EXPECT_EQ(b.serial, a.serial);
    EXPECT_EQ(b.last_used, a.last_used);
    EXPECT_EQ(b.signature, a.signature);
    EXPECT_EQ(cv::norm(a.panorama, b.panorama, cv::NORM_INF), 0.0);
    EXPECT_TRUE(graph.pose(id).isApprox(map.graph.pose(old_id[id]), 1e-12));
  }
  EXPECT_EQ(memory.leastRecentlyUsed(-1, -1), 0) << "the least recently used place is still first";
  int loops = 0;
  for (int e = 0; e < graph.edgeCount(); ++e) {
    const PoseGraph::Edge& edge = graph.edge(e);
    const PoseGraph::Edge& was = map.graph.edge(e);
    EXPECT_EQ(old_id[edge.from], was.from);
    EXPECT_EQ(old_id[edge.to], was.to);
    EXPECT_TRUE(edge.relative.isApprox(was.relative, 1e-12));
    EXPECT_EQ(edge.rotation_sigma, was.rotation_sigma);
    EXPECT_EQ(edge.position_sigma, was.position_sigma);
    loops += edge.loop ? 1 : 0;
  }
  EXPECT_EQ(loops, 1);
}

TEST(MapFile, TheFormatIsTheOneTheHeaderDescribes) {
  // The fuzzer's seed, written byte by byte from the file comment of map_file.hpp (Python's
  // struct and zlib.crc32), not by encodeMap: two places of 52 x 4 pixels and one edge; its
  // lens grid's x, y pairs are (i, -i) but the last, which is NaN (no bearing).
  const fs::path seed =
      fs::path(OMNIPOSE_SOURCE_DIR) / "tests/fuzz/corpus/fuzz_map_file/two_places.map";
  const std::string text = testing::readText(seed);
  MapSnapshot out;
  const auto ok = decodeMap({text.begin(), text.end()}, seed.string(), out);
  ASSERT_TRUE(ok.has_value()) << ok.error().message();
  for (int i = 0; i + 1 < LensGrid::kPoints; ++i) {
    EXPECT_EQ(out.lens.xy[2 * i], static_cast<float>(i));
    EXPECT_EQ(out.lens.xy[2 * i + 1], -static_cast<float>(i));
  }
  EXPECT_TRUE(std::isnan(out.lens.xy[2 * LensGrid::kPoints - 2]));
  EXPECT_TRUE(std::isnan(out.lens.xy[2 * LensGrid::kPoints - 1]));
  EXPECT_EQ(out.panorama, cv::Size(52, 4));
  ASSERT_EQ(out.place_count, 2);
  EXPECT_EQ(out.places[1].sequence, 101);
  EXPECT_EQ(out.places[1].serial, 2);
  EXPECT_NEAR(out.places[1].pose.translation().x(), 0.1, 1e-15);
  EXPECT_NEAR(std::atan2(out.places[1].pose(1, 0), out.places[1].pose(0, 0)), 0.01, 1e-12);
  EXPECT_EQ(out.places[1].panorama.at<std::uint8_t>(0, 1), 7 + 13);
  ASSERT_EQ(out.edges.size(), 1u);
  EXPECT_EQ(out.edges[0].to, 1);
  EXPECT_EQ(out.edges[0].rotation_sigma, 1e-3);
  EXPECT_FALSE(out.edges[0].loop);
}

TEST(MapFile, WhatIsNotAUsableMapIsRefusedNamingTheFileAndWhy) {
  const testing::TempDir tmp("map");
  const fs::path good = tmp / "good.map";
  ASSERT_TRUE(saveMap(good, snapshotOf(Map())).has_value());
  const std::string bytes = testing::readText(good);

  struct Case {
    std::string name;
    std::string content;
    std::string why;
  };
  std::vector<Case> cases;
  cases.push_back({"text.map", "hello\n", "not an omnipose map"});
  cases.push_back({"empty.map", {}, "not an omnipose map"});
  cases.push_back({"header_only.map", {bytes.begin(), bytes.begin() + 30}, "cut short"});
  cases.push_back({"cut.map", {bytes.begin(), bytes.end() - 1}, "cut short or grown"});
  std::string grown = bytes;
  grown.push_back('\0');
  cases.push_back({"grown.map", grown, "cut short or grown"});
  std::string damaged = bytes;
  damaged[bytes.size() / 2] ^= 0x10;
  cases.push_back({"damaged.map", damaged, "damaged"});
  std::string version = bytes;
  version[13] = 3;  // the u32 after the 13-byte magic
  cases.push_back({"version.map", version, "map version 3; this build reads version 2"});
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    tmp.write(c.name, c.content);
    MapSnapshot out;
    const auto got = loadMap(tmp / c.name, kCalibration, 8, out);
    ASSERT_FALSE(got.has_value());
    EXPECT_EQ(got.error().code(), ErrorCode::kInvalidArgument);
    EXPECT_THAT(got.error().message(), HasSubstr((tmp / c.name).string()));
    EXPECT_THAT(got.error().message(), HasSubstr(c.why));
    EXPECT_EQ(out.place_count, 0);
    EXPECT_TRUE(out.edges.empty());
  }

  MapSnapshot out;
  auto got = loadMap(good, calibrationOf({440, 22}), 8, out);
  ASSERT_FALSE(got.has_value());
  EXPECT_THAT(got.error().message(), HasSubstr("panoramas of 220 x 22 pixels; this calibration's are 440 x 22"));
  EXPECT_EQ(out.place_count, 0);
  got = loadMap(good, kCalibration, 4, out);
  ASSERT_FALSE(got.has_value()) << "5 places for a memory of 4";
  EXPECT_THAT(got.error().message(), HasSubstr(good.string()));
  EXPECT_EQ(out.place_count, 0);
  got = loadMap(tmp / "missing.map", kCalibration, 8, out);
  ASSERT_FALSE(got.has_value());
  EXPECT_EQ(got.error().code(), ErrorCode::kNotFound);
  EXPECT_THAT(got.error().message(), HasSubstr("missing.map"));
  ASSERT_EQ(::mkfifo((tmp / "fifo.map").c_str(), 0600), 0);
  got = loadMap(tmp / "fifo.map", kCalibration, 8, out);
  ASSERT_FALSE(got.has_value()) << "a FIFO without a writer neither blocks nor loads";
  EXPECT_THAT(got.error().message(), HasSubstr("FIFO"));
  ASSERT_TRUE(loadMap(good, kCalibration, 8, out).has_value()) << "the good one still loads";
  EXPECT_EQ(out.place_count, 5);
}

TEST(MapFile, AMapOfAnotherLensIsRefusedAndARecalibrationOfThisOneIsNot) {
  const testing::TempDir tmp("map");
  const fs::path path = tmp / "map.bin";
  ASSERT_TRUE(saveMap(path, snapshotOf(Map())).has_value());
  MapSnapshot out;
  const auto loadWith = [&](const Calibration& calibration) {
    return loadMap(path, calibration, 8, out);
  };

  Calibration recalibrated = kCalibration;  // the mirror's centre found half a pixel away
  recalibrated.omni.center_x += 0.5;
  EXPECT_TRUE(loadWith(recalibrated).has_value());
  EXPECT_NEAR(out.lens.farthestPx(LensGrid::of(recalibrated)), 0.5, 1e-3);

  struct Case {
    const char* what;
    Calibration calibration;
  };
  std::vector<Case> cases;
  cases.push_back({"centre 5 px away", kCalibration});
  cases.back().calibration.omni.center_y += 5.0;
  cases.push_back({"a larger ring", kCalibration});
  cases.back().calibration.omni.radius_outer += 20.0;
  cases.push_back({"the robot's front elsewhere", kCalibration});
  cases.back().calibration.omni.azimuth_zero_deg += 10.0;
  cases.push_back({"the panorama's forward column elsewhere", kCalibration});
  cases.back().calibration.panorama.forward_column += 10.0;
  cases.push_back({"the mirror's outer edge at the bottom", kCalibration});
  cases.back().calibration.omni.outer_edge = OuterEdge::kBottom;
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    const auto got = loadWith(c.calibration);
    ASSERT_FALSE(got.has_value());
    EXPECT_EQ(got.error().code(), ErrorCode::kInvalidArgument);
    EXPECT_THAT(got.error().message(), HasSubstr(path.string()));
    EXPECT_THAT(got.error().message(), HasSubstr("made with another calibration"));
    EXPECT_EQ(out.place_count, 0);
  }

  // A grid with no bearing where the calibration's has one (or not finite): never "near".
  LensGrid blind = LensGrid::of(kCalibration);
  blind.xy[4] = std::numeric_limits<float>::quiet_NaN();
  EXPECT_TRUE(std::isinf(blind.farthestPx(LensGrid::of(kCalibration))));
  EXPECT_TRUE(std::isinf(LensGrid::of(kCalibration).farthestPx(blind)));
  blind.xy[4] = std::numeric_limits<float>::infinity();
  EXPECT_TRUE(std::isinf(blind.farthestPx(LensGrid::of(kCalibration))));
  EXPECT_EQ(LensGrid().farthestPx(LensGrid()), 0.0) << "two grids never computed";
}

TEST(MapFile, AFileThatIsNotAMapIsNeverOverwritten) {
  const testing::TempDir tmp("map");
  MapSnapshot snapshot = snapshotOf(Map());
  const fs::path path = tmp.write("notes.txt", "keep\n");
  const auto got = saveMap(path, snapshot);
  ASSERT_FALSE(got.has_value());
  EXPECT_THAT(got.error().message(), HasSubstr(path.string()));
  EXPECT_EQ(testing::readText(path), "keep\n");
  // A map is replaced by the newer one.
  const fs::path map_path = tmp / "map.bin";
  ASSERT_TRUE(saveMap(map_path, snapshot).has_value());
  snapshot.place_count = 2;
  snapshot.edges.resize(1);
  ASSERT_TRUE(saveMap(map_path, snapshot).has_value());
  MapSnapshot out;
  ASSERT_TRUE(loadMap(map_path, kCalibration, 8, out).has_value());
  EXPECT_EQ(out.place_count, 2);
  EXPECT_EQ(out.edges.size(), 1u);
  int files = 0;
  for ([[maybe_unused]] const auto& entry : fs::directory_iterator(tmp.path())) ++files;
  EXPECT_EQ(files, 2) << "no temporary file left beside them";
}

TEST(MapFile, ASnapshotTooLargeForTheMemoryIsRefusedAndLeavesItEmpty) {
  const MapSnapshot snapshot = snapshotOf(Map());
  PlaceMemory memory(4, kPanorama);
  PoseGraph graph(4, 16);
  const auto got = restoreSnapshot(snapshot, memory, graph);
  ASSERT_FALSE(got.has_value());
  EXPECT_THAT(got.error().message(), HasSubstr("5 places, more than the 4 kept"));
  EXPECT_EQ(memory.size(), 0);
  EXPECT_EQ(graph.nodeCount(), 0);
}

TEST(MapFile, ASecondSnapshotAllocatesNothing) {
  if (!testing::AllocationCounter::available()) GTEST_SKIP() << "allocation counting unavailable";
  const Map map;
  MapSnapshot snapshot;
  takeSnapshot(map.memory, map.graph, snapshot);
  testing::AllocationCounter counter;
  takeSnapshot(map.memory, map.graph, snapshot);
  EXPECT_EQ(counter.stop(), 0);
  EXPECT_EQ(snapshot.place_count, 5);
}

}  // namespace
}  // namespace omnipose::map
