// DATASET/timestamps.txt and groundtruth.tum (the TUM reader, readTum), through
// Dataset::open with a valid calibration and three frame files: either every frame gets a
// finite timestamp (and no exposure or one in [0, 10] s) and every ground-truth pose is
// finite, or std::runtime_error names the file. The input's first half is timestamps.txt, its second half groundtruth.tum (present
// when the first byte is odd).
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "fuzz_support.hpp"
#include "omnipose/calibration.hpp"
#include "omnipose/io/dataset.hpp"

namespace {

const std::filesystem::path& dataset() {
  static const std::filesystem::path root = [] {
    const auto dir = omnipose::fuzz::scratch() / "dataset";
    std::filesystem::create_directories(dir / "frames");
    omnipose::Calibration{}.save(dir / "calibration.yaml");
    for (const char* name : {"000000.png", "000001.png", "000002.png"})
      omnipose::fuzz::writeFile(dir / "frames" / name, nullptr, 0);  // listed, never decoded
    return dir;
  }();
  return root;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const auto& root = dataset();
  const std::size_t half = size / 2;
  omnipose::fuzz::writeFile(root / "timestamps.txt", data, half);
  const bool with_tum = half > 0 && (data[0] & 1);
  if (with_tum) omnipose::fuzz::writeFile(root / "groundtruth.tum", data + half, size - half);
  else std::filesystem::remove(root / "groundtruth.tum");
  try {
    const omnipose::Dataset d = omnipose::Dataset::open(root);
    if (d.frames.size() != 3) __builtin_trap();
    for (const auto& f : d.frames) {
      if (!std::isfinite(f.timestamp)) __builtin_trap();
      // A recorded exposure is a number of seconds in [0, 10], or none (NaN).
      if (!std::isnan(f.exposure_s) && !(f.exposure_s >= 0.0 && f.exposure_s <= 10.0))
        __builtin_trap();
    }
    if (d.groundtruth) {
      for (const auto& p : *d.groundtruth)
        if (!std::isfinite(p.timestamp) || !p.pose.matrix().allFinite()) __builtin_trap();
    }
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    if (what.find("timestamps.txt") == std::string::npos &&
        what.find("groundtruth.tum") == std::string::npos)
      __builtin_trap();
  }
  return 0;
}
