#include "map/map_file.hpp"

#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <string_view>

#include "omnipose/file_io.hpp"

namespace omnipose::map {

static_assert(std::endian::native == std::endian::little,
              "the map file is little-endian and written as the memory holds it");

namespace {

constexpr std::string_view kMagic = "OMNIPOSE MAP\n";
constexpr std::uint32_t kVersion = 2;
constexpr std::size_t kSignatureFloats = std::tuple_size_v<PlaceSignature::Vector>;
constexpr std::size_t kLensBytes = std::tuple_size_v<decltype(LensGrid::xy)> * 4;
constexpr std::size_t kHeaderBytes = kMagic.size() + 5 * 4 + kLensBytes;
constexpr std::size_t kPoseBytes = 7 * 8;
/// A place without its panorama.
constexpr std::size_t kPlaceBytes = 5 * 8 + kPoseBytes + kSignatureFloats * 4;
constexpr std::size_t kEdgeBytes = 2 * 4 + kPoseBytes + 2 * 8 + 1;
/// Panoramas larger than this are no calibration's (limits: 16384 x 4096).
constexpr std::uint32_t kMaxSide = 1u << 16;

class Writer {
 public:
  explicit Writer(std::string& out) : out_(out) {}
  template <typename T>
  void put(T value) {
    char bytes[sizeof(T)];
    std::memcpy(bytes, &value, sizeof(T));
    out_.append(bytes, sizeof(T));
  }
  void putBytes(const void* data, std::size_t n) { out_.append(static_cast<const char*>(data), n); }
  void putPose(const Eigen::Isometry3d& T) {
    const Eigen::Quaterniond q(T.linear());
    for (double v : {q.w(), q.x(), q.y(), q.z()}) put(v);
    for (int i = 0; i < 3; ++i) put(T.translation()[i]);
  }

 private:
  std::string& out_;
};

/// Reads in order from bytes whose size the caller has checked against the header's counts.
class Reader {
 public:
  explicit Reader(const std::uint8_t* data) : data_(data) {}
  template <typename T>
  T get() {
    T value;
    std::memcpy(&value, data_ + at_, sizeof(T));
    at_ += sizeof(T);
    return value;
  }
  const std::uint8_t* take(std::size_t n) {
    const std::uint8_t* p = data_ + at_;
    at_ += n;
    return p;
  }
  /// A pose; false when it is not finite or its quaternion is not of unit length.
  bool getPose(Eigen::Isometry3d& T) {
    double q[4], t[3];
    for (double& v : q) v = get<double>();
    for (double& v : t) v = get<double>();
    const Eigen::Quaterniond quaternion(q[0], q[1], q[2], q[3]);
    const double norm = quaternion.norm();
    if (!std::isfinite(norm) || std::abs(norm - 1.0) > 1e-6) return false;
    if (!std::isfinite(t[0]) || !std::isfinite(t[1]) || !std::isfinite(t[2])) return false;
    T = Eigen::Isometry3d::Identity();
    T.linear() = quaternion.normalized().toRotationMatrix();
    T.translation() = Eigen::Vector3d(t[0], t[1], t[2]);
    return true;
  }

 private:
  const std::uint8_t* data_;
  std::size_t at_ = 0;
};

std::uint32_t crc32Of(const std::uint8_t* data, std::size_t n) {
  uLong crc = crc32(0L, Z_NULL, 0);
  // zlib takes at most uInt bytes a call.
  while (n > 0) {
    const auto chunk = static_cast<uInt>(std::min<std::size_t>(n, 1u << 30));
    crc = crc32(crc, data, chunk);
    data += chunk;
    n -= chunk;
  }
  return static_cast<std::uint32_t>(crc);
}

constexpr FileKind kMapKind{"omnipose map", looksLikeMapFile};

}  // namespace

bool looksLikeMapFile(std::string_view head) { return head.starts_with(kMagic); }

LensGrid::LensGrid() { xy.fill(std::numeric_limits<float>::quiet_NaN()); }

LensGrid LensGrid::of(const Calibration& calibration) {
  LensGrid grid;
  const double W = calibration.panorama.width, H = calibration.panorama.height;
  for (int row = 0; row < kRows; ++row) {
    const double v = (H - 1.0) * row / (kRows - 1);
    for (int column = 0; column < kColumns; ++column) {
      const double u = (column + 0.5) * W / kColumns - 0.5;
      const Eigen::Vector2d p = calibration.omniPixel(u, v);
      const std::size_t i = 2 * static_cast<std::size_t>(row * kColumns + column);
      grid.xy[i] = static_cast<float>(p.x());
      grid.xy[i + 1] = static_cast<float>(p.y());
    }
  }
  return grid;
}

double LensGrid::farthestPx(const LensGrid& other) const {
  double farthest = 0.0;
  for (std::size_t i = 0; i < xy.size(); i += 2) {
    const bool seen = !std::isnan(xy[i]) && !std::isnan(xy[i + 1]);
    const bool other_seen = !std::isnan(other.xy[i]) && !std::isnan(other.xy[i + 1]);
    if (!seen && !other_seen) continue;
    if (!seen || !other_seen) return std::numeric_limits<double>::infinity();
    const double d =
        std::hypot(double{xy[i]} - other.xy[i], double{xy[i + 1]} - other.xy[i + 1]);
    if (!std::isfinite(d)) return std::numeric_limits<double>::infinity();
    farthest = std::max(farthest, d);
  }
  return farthest;
}

void reserveSnapshot(MapSnapshot& out, cv::Size panorama, int places, int edges) {
  out.panorama = panorama;
  const auto n = static_cast<std::size_t>(std::max(places, 0));
  if (out.places.size() < n) out.places.resize(n);
  for (SavedPlace& p : out.places)
    if (p.panorama.size() != panorama || p.panorama.type() != CV_8UC1)
      p.panorama = cv::Mat::zeros(panorama, CV_8UC1);
  out.place_count = std::min(out.place_count, static_cast<int>(out.places.size()));
  if (out.edges.capacity() < static_cast<std::size_t>(std::max(edges, 0)))
    out.edges.reserve(static_cast<std::size_t>(edges));
}

void takeSnapshot(const PlaceMemory& memory, const PoseGraph& graph, MapSnapshot& out) {
  const cv::Size panorama = memory.capacity() > 0 ? memory[0].panorama.size() : cv::Size();
  // Room for the largest graph: later snapshots allocate nothing.
  reserveSnapshot(out, panorama, memory.capacity(), graph.maxEdges());
  // The snapshot's number of each live place, by increasing id (node 0 stays first).
  std::vector<int>& index = out.index;
  index.assign(static_cast<std::size_t>(memory.capacity()), -1);
  out.place_count = 0;
  for (int id = 0; id < memory.capacity(); ++id) {
    const Place& p = memory[id];
    if (!p.valid || !graph.alive(id)) continue;
    index[static_cast<std::size_t>(id)] = out.place_count;
    SavedPlace& s = out.places[static_cast<std::size_t>(out.place_count++)];
    s.sequence = p.sequence;
    s.time_s = p.time_s;
    s.yaw_rate = p.yaw_rate;
    s.serial = p.serial;
    s.last_used = p.last_used;
    s.pose = graph.pose(id);
    s.signature = p.signature;
    p.panorama.copyTo(s.panorama);
  }
  out.edges.clear();
  for (int e = 0; e < graph.edgeCount(); ++e) {
    PoseGraph::Edge edge = graph.edge(e);
    if (edge.from < 0 || edge.to < 0 || edge.from >= memory.capacity() ||
        edge.to >= memory.capacity())
      continue;
    edge.from = index[static_cast<std::size_t>(edge.from)];
    edge.to = index[static_cast<std::size_t>(edge.to)];
    if (edge.from >= 0 && edge.to >= 0) out.edges.push_back(edge);
  }
}

Expected<void> restoreSnapshot(const MapSnapshot& snapshot, PlaceMemory& memory,
                               PoseGraph& graph) {
  memory.clear();
  graph.clear();
  const int places = snapshot.place_count;
  const cv::Size panorama = memory.capacity() > 0 ? memory[0].panorama.size() : cv::Size();
  if (places > 0 && snapshot.panorama != panorama)
    return fail(ErrorCode::kInvalidArgument, "panoramas of %d x %d pixels, not %d x %d",
                snapshot.panorama.width, snapshot.panorama.height, panorama.width,
                panorama.height);
  if (places > memory.capacity() || places > graph.maxNodes())
    return fail(ErrorCode::kInvalidArgument, "%d places, more than the %d kept", places,
                std::min(memory.capacity(), graph.maxNodes()));
  for (int i = 0; i < places; ++i) {
    const SavedPlace& p = snapshot.places[static_cast<std::size_t>(i)];
    const int id = graph.addNode(p.pose);
    memory.restore(id, p.panorama, p.signature, p.sequence, p.time_s, p.yaw_rate, p.serial,
                   p.last_used);
  }
  for (const PoseGraph::Edge& e : snapshot.edges) {
    if (!graph.addEdge(e)) {
      const int kept = graph.edgeCount();
      memory.clear();
      graph.clear();
      return fail(ErrorCode::kInvalidArgument,
                  "edge %d-%d names no place, or the graph is full at %d edges", e.from, e.to,
                  kept);
    }
  }
  return {};
}

std::string encodeMap(const MapSnapshot& snapshot) {
  const std::size_t pixels = static_cast<std::size_t>(snapshot.panorama.area());
  std::string out;
  const auto places = static_cast<std::size_t>(snapshot.place_count);
  out.reserve(kHeaderBytes + places * (kPlaceBytes + pixels) + snapshot.edges.size() * kEdgeBytes +
              4);
  Writer w(out);
  w.putBytes(kMagic.data(), kMagic.size());
  w.put<std::uint32_t>(kVersion);
  w.put<std::uint32_t>(static_cast<std::uint32_t>(snapshot.panorama.width));
  w.put<std::uint32_t>(static_cast<std::uint32_t>(snapshot.panorama.height));
  w.put<std::uint32_t>(static_cast<std::uint32_t>(places));
  w.put<std::uint32_t>(static_cast<std::uint32_t>(snapshot.edges.size()));
  w.putBytes(snapshot.lens.xy.data(), kLensBytes);
  for (std::size_t i = 0; i < places; ++i) {
    const SavedPlace& p = snapshot.places[i];
    w.put<std::int64_t>(p.sequence);
    w.put<double>(p.time_s);
    w.put<double>(p.yaw_rate);
    w.put<std::int64_t>(p.serial);
    w.put<std::int64_t>(p.last_used);
    w.putPose(p.pose);
    w.putBytes(p.signature.data(), kSignatureFloats * sizeof(float));
    for (int r = 0; r < p.panorama.rows; ++r)
      w.putBytes(p.panorama.ptr<std::uint8_t>(r), static_cast<std::size_t>(p.panorama.cols));
  }
  for (const PoseGraph::Edge& e : snapshot.edges) {
    w.put<std::uint32_t>(static_cast<std::uint32_t>(e.from));
    w.put<std::uint32_t>(static_cast<std::uint32_t>(e.to));
    w.putPose(e.relative);
    w.put<double>(e.rotation_sigma);
    w.put<double>(e.position_sigma);
    w.put<std::uint8_t>(e.loop ? 1 : 0);
  }
  w.put<std::uint32_t>(crc32Of(reinterpret_cast<const std::uint8_t*>(out.data()), out.size()));
  return out;
}

Expected<void> decodeMap(const std::vector<std::uint8_t>& bytes, const std::string& what,
                         MapSnapshot& out) {
  const char* name = what.c_str();
  const std::string_view head(reinterpret_cast<const char*>(bytes.data()),
                              std::min(bytes.size(), kMagic.size()));
  if (!looksLikeMapFile(head))
    return fail(ErrorCode::kInvalidArgument, "%s: not an omnipose map (no \"OMNIPOSE MAP\" magic)", name);
  if (bytes.size() < kHeaderBytes + 4)
    return fail(ErrorCode::kInvalidArgument, "%s: cut short: %zu bytes, no complete header", name,
                bytes.size());
  Reader r(bytes.data());
  r.take(kMagic.size());
  const auto version = r.get<std::uint32_t>();
  if (version != kVersion)
    return fail(ErrorCode::kInvalidArgument, "%s: map version %u; this build reads version %u",
                name, version, kVersion);
  const auto width = r.get<std::uint32_t>(), height = r.get<std::uint32_t>();
  const auto places = r.get<std::uint32_t>(), edges = r.get<std::uint32_t>();
  if (width == 0 || height == 0 || width > kMaxSide || height > kMaxSide)
    return fail(ErrorCode::kInvalidArgument, "%s: panoramas of %u x %u pixels", name, width,
                height);
  const std::size_t expected = kHeaderBytes +
                               std::size_t{places} * (kPlaceBytes + std::size_t{width} * height) +
                               std::size_t{edges} * kEdgeBytes + 4;
  if (places > 65536 || edges > 1u << 20 || bytes.size() != expected)
    return fail(ErrorCode::kInvalidArgument,
                "%s: %zu bytes where %u places and %u edges of %u x %u panoramas take %zu "
                "(cut short or grown)",
                name, bytes.size(), places, edges, width, height, expected);
  std::uint32_t stored_crc;
  std::memcpy(&stored_crc, bytes.data() + bytes.size() - 4, 4);
  if (crc32Of(bytes.data(), bytes.size() - 4) != stored_crc)
    return fail(ErrorCode::kInvalidArgument, "%s: damaged (its CRC-32 does not match)", name);

  const cv::Size panorama(static_cast<int>(width), static_cast<int>(height));
  reserveSnapshot(out, panorama, static_cast<int>(places), static_cast<int>(edges));
  std::memcpy(out.lens.xy.data(), r.take(kLensBytes), kLensBytes);
  out.place_count = 0;
  for (std::uint32_t i = 0; i < places; ++i) {
    SavedPlace& p = out.places[i];
    p.sequence = r.get<std::int64_t>();
    p.time_s = r.get<double>();
    p.yaw_rate = r.get<double>();
    p.serial = static_cast<long>(r.get<std::int64_t>());
    p.last_used = static_cast<long>(r.get<std::int64_t>());
    if (!r.getPose(p.pose) || !std::isfinite(p.time_s) || !std::isfinite(p.yaw_rate))
      return fail(ErrorCode::kInvalidArgument, "%s: place %u: not a pose", name, i);
    std::memcpy(p.signature.data(), r.take(kSignatureFloats * sizeof(float)),
                kSignatureFloats * sizeof(float));
    const std::uint8_t* pixels = r.take(std::size_t{width} * height);
    for (int row = 0; row < p.panorama.rows; ++row)
      std::memcpy(p.panorama.ptr<std::uint8_t>(row), pixels + std::size_t(row) * width, width);
  }
  out.place_count = static_cast<int>(places);
  out.edges.clear();
  for (std::uint32_t i = 0; i < edges; ++i) {
    PoseGraph::Edge e;
    const auto from = r.get<std::uint32_t>(), to = r.get<std::uint32_t>();
    const bool pose_ok = r.getPose(e.relative);
    e.rotation_sigma = r.get<double>();
    e.position_sigma = r.get<double>();
    const auto loop = r.get<std::uint8_t>();
    if (from >= places || to >= places || from == to)
      return fail(ErrorCode::kInvalidArgument, "%s: edge %u joins places %u and %u of %u", name,
                  i, from, to, places);
    if (!pose_ok || !(e.rotation_sigma > 0.0) || !(e.position_sigma > 0.0) ||
        !std::isfinite(e.rotation_sigma) || !std::isfinite(e.position_sigma) || loop > 1)
      return fail(ErrorCode::kInvalidArgument, "%s: edge %u: not a relative pose with its sigmas",
                  name, i);
    e.from = static_cast<int>(from);
    e.to = static_cast<int>(to);
    e.loop = loop == 1;
    out.edges.push_back(e);
  }
  return {};
}

Expected<void> saveMap(const std::filesystem::path& path, const MapSnapshot& snapshot) {
  return writeFileAtomically(path, encodeMap(snapshot), kMapKind);
}

Expected<void> loadMap(const std::filesystem::path& path, const Calibration& calibration,
                       int max_places, MapSnapshot& out) {
  const cv::Size panorama(calibration.panorama.width, calibration.panorama.height);
  out.place_count = 0;
  out.edges.clear();
  const std::uintmax_t max_bytes =
      kHeaderBytes +
      static_cast<std::uintmax_t>(std::max(max_places, 0)) *
          (kPlaceBytes + static_cast<std::uintmax_t>(std::max(panorama.area(), 0)) +
           4 * kEdgeBytes) +
      4;
  std::vector<std::uint8_t> bytes;
  if (Expected<void> read = readRegularFile(path, max_bytes, bytes); !read)
    return std::unexpected(read.error());
  const std::string what = path.string();
  const auto refuse = [&](Expected<void> why) {
    out.place_count = 0;
    out.edges.clear();
    return why;
  };
  if (Expected<void> ok = decodeMap(bytes, what, out); !ok) return refuse(ok);
  if (out.place_count > 0 && out.panorama != panorama)
    return refuse(fail(ErrorCode::kInvalidArgument,
                       "%s: panoramas of %d x %d pixels; this calibration's are %d x %d",
                       what.c_str(), out.panorama.width, out.panorama.height, panorama.width,
                       panorama.height));
  if (const double moved = out.lens.farthestPx(LensGrid::of(calibration));
      out.place_count > 0 && !(moved <= kLensGridTolerancePx)) {
    if (std::isinf(moved))
      return refuse(fail(ErrorCode::kInvalidArgument,
                         "%s: made with another calibration: its lens sees panorama pixels "
                         "this calibration's does not, or the reverse",
                         what.c_str()));
    return refuse(fail(ErrorCode::kInvalidArgument,
                       "%s: made with another calibration: its panorama pixels fall up to %.1f "
                       "frame pixels from this calibration's (tolerance %.1f: another lens, "
                       "mirror centre or panorama geometry)",
                       what.c_str(), moved, kLensGridTolerancePx));
  }
  if (out.place_count > max_places)
    return refuse(fail(ErrorCode::kInvalidArgument, "%s: %d places, more than the %d kept",
                       what.c_str(), out.place_count, max_places));
  return {};
}

}  // namespace omnipose::map
