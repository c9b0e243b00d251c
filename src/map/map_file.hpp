#pragma once
/// \file map_file.hpp
/// The map on disk (private to the core library): the places of a PlaceMemory and the pose
/// graph over them, as a snapshot and as a file, so that a map survives a restart.
///
/// A snapshot is a copy of the map taken on the frame's thread (takeSnapshot(): no
/// allocation once the snapshot has held as many places, a memcpy of each place's panorama)
/// and written from another thread (saveMap()); its nodes are numbered 0..n-1 in the order of
/// the graph's ids, so node 0, the gauge, stays node 0.
///
/// The file (little-endian, version 2):
///
///     "OMNIPOSE MAP\n"               13 bytes, the magic
///     u32 version, u32 panorama width, u32 panorama height, u32 places, u32 edges
///     f32 lens[2 * LensGrid::kPoints]  the lens grid (x, y pairs; NaN where no bearing)
///     per place:  i64 sequence, f64 time_s, f64 yaw_rate, i64 serial, i64 last_used,
///                 f64 rotation[4] (quaternion w x y z), f64 position[3] (scene distances),
///                 f32 signature[PlaceSignature::kBands * kHarmonics], u8 panorama[w * h]
///     per edge:   u32 from, u32 to, f64 rotation[4], f64 position[3],
///                 f64 rotation_sigma, f64 position_sigma, u8 loop
///     u32 CRC-32 (zlib's) of every byte before it
///
/// It is written atomically (a temporary file beside it, flushed, renamed over it:
/// file_io.hpp), so a kill or a power cut leaves the old map or the new one, never half of
/// one; an existing file that is not an omnipose map is never overwritten. Loading refuses a
/// file that is not a regular file, is not a map (the magic), of another version, cut short
/// or grown, damaged (the CRC), whose panoramas are not this calibration's (their size, or
/// its lens grid farther than kLensGridTolerancePx from the file's: another lens, mirror
/// centre or panorama geometry, under which the places would not look like the frames), or
/// more than the memory holds, naming the file and the reason.

#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "map/place_memory.hpp"
#include "map/pose_graph.hpp"
#include "omnipose/calibration.hpp"
#include "omnipose/error.hpp"

namespace omnipose::map {

struct SavedPlace {
  std::int64_t sequence = -1;
  double time_s = 0.0;
  double yaw_rate = 0.0;
  long serial = 0;
  long last_used = 0;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();  ///< its node's, map frame
  PlaceSignature::Vector signature{};
  cv::Mat panorama;  ///< CV_8UC1
};

/// What a panorama pixel means besides the panorama's size: where the calibration puts a grid
/// of panorama pixels in the frame. A map keeps its calibration's; loadMap() compares it with
/// the running one's.
struct LensGrid {
  static constexpr int kColumns = 8;  ///< panorama columns (u + 0.5) = (i + 0.5) W / kColumns
  static constexpr int kRows = 3;     ///< the panorama's top, middle and bottom rows
  static constexpr int kPoints = kColumns * kRows;
  /// Frame pixel x, y of point i at 2i, 2i + 1 (Calibration::omniPixel()); NaN where the lens
  /// sees no bearing, and everywhere in a grid never computed.
  std::array<float, 2 * kPoints> xy;

  LensGrid();  ///< all NaN
  static LensGrid of(const Calibration& calibration);
  /// The largest distance between the two grids' points, frame pixels: 0 for the same
  /// calibration, infinity where one grid has a bearing and the other none or a coordinate
  /// is not finite.
  double farthestPx(const LensGrid& other) const;
};

/// A map whose lens grid is farther than this from the calibration's is refused (frame
/// pixels). A recalibration of the same camera that moves it less keeps the map; a mirror
/// centre 2 pixels away shifts the panorama's rows by about a row on the default lens.
inline constexpr double kLensGridTolerancePx = 2.0;

struct MapSnapshot {
  cv::Size panorama;
  /// The calibration's (Odometry::snapshotMap() fills it; takeSnapshot() leaves it alone).
  LensGrid lens;
  /// Node i of the snapshot is places[i], i < place_count; the slots after them keep their
  /// panoramas allocated for later snapshots.
  int place_count = 0;
  std::vector<SavedPlace> places;
  std::vector<PoseGraph::Edge> edges;  ///< from/to index places
  std::vector<int> index;              ///< takeSnapshot()'s scratch: graph id -> node
};

/// Copies the places of `memory` (those whose node is alive in `graph`) and the edges
/// between them into `out`, renumbered. Allocates only the first time (room for the
/// memory's capacity and the graph's edges then).
void takeSnapshot(const PlaceMemory& memory, const PoseGraph& graph, MapSnapshot& out);
/// Makes room in `out` for `places` places of `panorama` pixels (their panoramas allocated)
/// and `edges` edges.
void reserveSnapshot(MapSnapshot& out, cv::Size panorama, int places, int edges);

/// Replaces the contents of `memory` and `graph` with the snapshot's (both cleared first).
/// kInvalidArgument, leaving both empty, when the snapshot does not fit: panoramas of
/// another size, more places than either holds, more edges than the graph holds, or an
/// edge naming no place.
Expected<void> restoreSnapshot(const MapSnapshot& snapshot, PlaceMemory& memory,
                               PoseGraph& graph);

/// The file's bytes for `snapshot`.
std::string encodeMap(const MapSnapshot& snapshot);
/// Parses a file's bytes into `out`; `what` names the file in errors (kInvalidArgument).
Expected<void> decodeMap(const std::vector<std::uint8_t>& bytes, const std::string& what,
                         MapSnapshot& out);

/// Writes `snapshot` to `path` atomically (see the file comment). Errors name the path.
Expected<void> saveMap(const std::filesystem::path& path, const MapSnapshot& snapshot);
/// Reads `path` into `out`: kNotFound when there is no file, kInvalidArgument for a file
/// that is not a usable map (the reason after the path), kIoError. At most `max_places`
/// places (the memory's capacity) of `calibration`'s panoramas (its size and lens grid) are
/// accepted.
Expected<void> loadMap(const std::filesystem::path& path, const Calibration& calibration,
                       int max_places, MapSnapshot& out);

/// Whether the first bytes of a file are an omnipose map's (its magic).
bool looksLikeMapFile(std::string_view head);

}  // namespace omnipose::map
