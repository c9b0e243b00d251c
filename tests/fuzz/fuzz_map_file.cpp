// The map file (src/map/map_file.hpp) as loadMap() reads it: decodeMap on arbitrary bytes,
// with the input's last four bytes replaced by the CRC-32 of the others (so that the fuzzer
// reaches past the checksum to the counts, poses and edges). Either an error naming the file,
// or a snapshot whose lens grid compares with a calibration's and that restores into a memory
// and a graph of its size and solves.
#include <zlib.h>

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "map/map_file.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace map = omnipose::map;
  std::vector<std::uint8_t> bytes(data, data + size);
  if (bytes.size() >= 4) {
    const auto crc = static_cast<std::uint32_t>(
        crc32(crc32(0L, Z_NULL, 0), bytes.data(), static_cast<uInt>(bytes.size() - 4)));
    std::memcpy(bytes.data() + bytes.size() - 4, &crc, 4);
  }
  map::MapSnapshot snapshot;
  const auto decoded = map::decodeMap(bytes, "fuzz.map", snapshot);
  if (!decoded) {
    if (decoded.error().message().rfind("fuzz.map: ", 0) != 0) __builtin_trap();
    return 0;
  }
  // The file's lens grid against a calibration's: a distance, or infinity, never NaN.
  static const map::LensGrid kLens = map::LensGrid::of(omnipose::Calibration{});
  if (!(snapshot.lens.farthestPx(kLens) >= 0.0)) __builtin_trap();
  const int places = snapshot.place_count;
  if (places < 0 || places > static_cast<int>(snapshot.places.size())) __builtin_trap();
  if (places == 0 || places > 256 || snapshot.panorama.width < 2 * 24 + 1 ||
      snapshot.panorama.height < 4)
    return 0;  // a memory for it would be the fuzzer's cost, not the reader's
  map::PlaceMemory memory(places, snapshot.panorama);
  map::PoseGraph graph(places, std::max<int>(places, static_cast<int>(snapshot.edges.size())));
  if (!map::restoreSnapshot(snapshot, memory, graph)) __builtin_trap();
  if (memory.size() != places || graph.nodeCount() != places) __builtin_trap();
  graph.solve();
  return 0;
}
