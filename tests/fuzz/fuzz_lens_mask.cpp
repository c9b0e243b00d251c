// Lens-model and mask loading through Calibration::load: a calibration.yaml and the files it
// names, all from one input. Layout (lengths little-endian; a length larger than what is
// left takes what is left; a missing part is an empty file):
//   [u16 n1][n1 bytes]  calibration.yaml
//   [u16 n2][n2 bytes]  calib_results.txt   (an OCamCalib model: omni.ocamcalib_file)
//   [u16 n3][n3 bytes]  omnidir.yml         (a Mei / cv::omnidir cv::FileStorage: omni.omnidir_file)
//   [the rest]          mask.png            (omni.mask; any image format cv::imread reads)
// The four files are written into a scratch directory and calibration.yaml is loaded from
// there (its relative names resolve beside it). A calibration.yaml containing '/' or '\' is
// skipped: it could name a file outside the scratch directory (/dev/zero ...).
// Load either throws a std::exception (a clean rejection) or returns a calibration that
// validates, whose mask (if any) is 8-bit grey of the image size, whose pixel <-> bearing
// mapping stays finite where it answers, and that load() reads back once save() wrote it
// (save() may refuse with std::runtime_error, e.g. a mask named with no image extension).
// A crash or a sanitizer report is a finding.
#include <cmath>
#include <cstdint>
#include <exception>
#include <filesystem>
#include <string_view>

#include "fuzz_support.hpp"
#include "omnipose/calibration.hpp"

namespace {

struct Reader {
  const std::uint8_t* data;
  std::size_t size;

  /// The next length-prefixed part.
  std::string_view part() {
    std::size_t n = 0;
    if (size >= 2) {
      n = static_cast<std::size_t>(data[0]) | (static_cast<std::size_t>(data[1]) << 8);
      data += 2;
      size -= 2;
    } else {
      data += size;
      size = 0;
    }
    if (n > size) n = size;
    const std::string_view p(reinterpret_cast<const char*>(data), n);
    data += n;
    size -= n;
    return p;
  }
  std::string_view rest() {
    const std::string_view p(reinterpret_cast<const char*>(data), size);
    data += size;
    size = 0;
    return p;
  }
};

void write(const std::filesystem::path& path, std::string_view bytes) {
  omnipose::fuzz::writeFile(path, reinterpret_cast<const std::uint8_t*>(bytes.data()), bytes.size());
}

void exercise(const omnipose::Calibration& c) {
  if (!c.validate().empty()) __builtin_trap();  // load() must not return an invalid one
  const auto& o = c.omni;
  if (!o.mask.empty() &&
      (o.mask.type() != CV_8UC1 || o.mask.cols != o.image_width || o.mask.rows != o.image_height))
    __builtin_trap();
  // Across the used ring, four azimuths: bearing of the pixel, pixel of that bearing.
  for (int k = 0; k <= 4; ++k) {
    const double r = o.radius_inner + (o.radius_outer - o.radius_inner) * k / 4.0;
    for (const auto& [dx, dy] : {std::pair{1.0, 0.0}, {0.0, 1.0}, {-1.0, 0.0}, {0.0, -1.0}}) {
      const auto b = c.bearingOfPixel(o.center_x + r * dx, o.center_y + r * dy);
      if (!b) continue;
      if (!b->allFinite()) __builtin_trap();
      const auto p = c.pixelOfBearing(*b);
      if (p && !p->allFinite()) __builtin_trap();
    }
  }
  // Panorama -> omni pixel: the corners and the horizon row.
  const auto& pano = c.panorama;
  for (const double v : {0.0, pano.horizon_row, pano.height - 1.0})
    for (const double u : {0.0, 0.5 * pano.width, pano.width - 1.0}) (void)c.omniPixel(u, v);
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  Reader in{data, size};
  const std::string_view yaml = in.part();
  if (yaml.find_first_of("/\\") != std::string_view::npos) return 0;
  const std::string_view ocamcalib = in.part();
  const std::string_view omnidir = in.part();
  const std::string_view mask = in.rest();

  const auto& dir = omnipose::fuzz::scratch();
  write(dir / "calibration.yaml", yaml);
  write(dir / "calib_results.txt", ocamcalib);
  write(dir / "omnidir.yml", omnidir);
  write(dir / "mask.png", mask);

  omnipose::Calibration c;
  try {
    c = omnipose::Calibration::load(dir / "calibration.yaml");
  } catch (const std::exception&) {
    return 0;
  }
  exercise(c);
  // What save() writes (the YAML, the OCamCalib text and the mask beside it) must load.
  const auto out = dir / "saved";
  std::filesystem::create_directories(out);
  try {
    c.save(out / "calibration.yaml");
  } catch (const std::runtime_error&) {
    return 0;
  }
  const omnipose::Calibration d = omnipose::Calibration::load(out / "calibration.yaml");
  if (d.omni.model != c.omni.model || d.omni.mask.empty() != c.omni.mask.empty()) __builtin_trap();
  return 0;
}
