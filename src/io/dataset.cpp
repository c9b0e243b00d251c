#include "omnipose/io/dataset.hpp"

#include "common/problem_list.hpp"
#include "io/text_records.hpp"
#include "omnipose/file_io.hpp"
#include "omnipose/image_decode.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <stdexcept>

namespace omnipose {
namespace fs = std::filesystem;

bool isImageFile(const fs::path& path) {
  std::string ext = path.extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
  return ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".pgm" || ext == ".ppm" ||
         ext == ".bmp";
}

namespace {

constexpr double kMaxTimestamp = 1e10;
constexpr std::size_t kMaxWarnings = 20;

/// Longest exposure timestamps.txt may state, seconds.
constexpr double kMaxStatedExposure = 10.0;

struct Stamp {
  double time = 0.0;
  double exposure = std::numeric_limits<double>::quiet_NaN();
  int line = 0;
};

/// timestamps.txt: "<file name> <seconds> [<exposure seconds>]" per line. A malformed line, a
/// value that is not a plain decimal, a time beyond +-1e10 s, an exposure outside [0, 10] s
/// or a name given twice is an error naming the line.
std::map<std::string, Stamp, std::less<>> readTimestamps(const fs::path& path) {
  const std::string text = readTextFileOrThrow(path);
  std::map<std::string, Stamp, std::less<>> stamps;
  const auto where = [&](int line) { return path.string() + ":" + std::to_string(line) + ": "; };
  for (const io::TextRecord& r : io::splitRecords(text)) {
    if (r.fields.size() < 2)
      throw std::runtime_error(where(r.line) + "expected '<file name> <seconds>'");
    const std::optional<double> t = io::parseDecimal(r.fields[1]);
    if (!t)
      throw std::runtime_error(where(r.line) + "'" + detail::shown(r.fields[1]) +
                               "' is not a decimal number of seconds");
    // Within +-1e10 s (year 2286): pacing converts to integer microseconds.
    if (!(std::abs(*t) <= kMaxTimestamp))
      throw std::runtime_error(where(r.line) +
                               "timestamp must be a finite number of seconds within +-1e10");
    Stamp stamp{*t, std::numeric_limits<double>::quiet_NaN(), r.line};
    if (r.fields.size() >= 3) {
      const std::optional<double> e = io::parseDecimal(r.fields[2]);
      if (!e || !(*e >= 0.0 && *e <= kMaxStatedExposure))
        throw std::runtime_error(where(r.line) + "exposure '" + detail::shown(r.fields[2]) +
                                 "' is not a decimal number of seconds in [0, 10]");
      stamp.exposure = *e;
    }
    const auto [it, inserted] = stamps.try_emplace(std::string(r.fields[0]), stamp);
    if (!inserted)
      throw std::runtime_error(where(r.line) + detail::shown(r.fields[0]) + " given twice (first on line " +
                               std::to_string(it->second.line) + ")");
  }
  return stamps;
}

}  // namespace

Dataset Dataset::open(const fs::path& root, const std::optional<fs::path>& calibration_override) {
  if (!fs::is_directory(root)) throw std::runtime_error(root.string() + ": no such dataset directory");
  Dataset d;
  d.root = root;
  d.calibration = Calibration::load(calibration_override ? *calibration_override
                                                         : root / "calibration.yaml");

  const fs::path frames_dir = root / "frames";
  if (!fs::is_directory(frames_dir))
    throw std::runtime_error(frames_dir.string() + ": missing frames directory");
  for (const auto& entry : fs::directory_iterator(frames_dir)) {
    if (entry.is_regular_file() && isImageFile(entry.path())) d.frames.push_back({entry.path(), 0.0});
  }
  if (d.frames.empty()) throw std::runtime_error(frames_dir.string() + ": no image files");
  std::sort(d.frames.begin(), d.frames.end(),
            [](const DatasetFrame& a, const DatasetFrame& b) { return a.path.filename() < b.path.filename(); });

  const fs::path stamps_path = root / "timestamps.txt";
  if (fs::exists(fs::symlink_status(stamps_path))) {
    const auto stamps = readTimestamps(stamps_path);
    std::size_t warned = 0, unwarned = 0;
    const auto warn = [&](const std::string& text) {
      if (warned < kMaxWarnings) {
        d.warnings.push_back(text);
        ++warned;
      } else {
        ++unwarned;
      }
    };
    for (std::size_t i = 0; i < d.frames.size(); ++i) {
      DatasetFrame& f = d.frames[i];
      const auto it = stamps.find(f.path.filename().string());
      if (it == stamps.end()) {
        throw std::runtime_error(stamps_path.string() + ": no timestamp for frame " +
                                 f.path.filename().string());
      }
      f.exposure_s = it->second.exposure;
      // The camera's stamp moved to the first row's capture time (sensor.timestamp).
      const SensorTiming& sensor = d.calibration.sensor;
      f.timestamp = it->second.time + sensor.captureTimeOffset(sensor.exposureOf(f.exposure_s));
      const std::string where = stamps_path.string() + ":" + std::to_string(it->second.line) + ": ";
      if (f.timestamp < 0.0)
        warn(where + f.path.filename().string() + " at " + std::to_string(f.timestamp) +
             " s: a negative time");
      if (i > 0 && !(f.timestamp > d.frames[i - 1].timestamp))
        warn(where + f.path.filename().string() + " at " + std::to_string(f.timestamp) +
             " s is not after the frame before it (" + d.frames[i - 1].path.filename().string() +
             " at " + std::to_string(d.frames[i - 1].timestamp) +
             " s): not linked to it by time; the pipeline finds it again by the ring search");
    }
    if (unwarned > 0)
      d.warnings.push_back("and " + std::to_string(unwarned) + " more timestamp warnings");
    d.timestamps_from_file = true;
  } else {
    for (std::size_t i = 0; i < d.frames.size(); ++i) d.frames[i].timestamp = i / kDefaultFps;
  }

  const fs::path gt_path = root / "groundtruth.tum";
  if (fs::exists(fs::symlink_status(gt_path))) d.groundtruth = readTum(gt_path);
  if (const fs::path imu = root / "imu.csv"; fs::exists(fs::symlink_status(imu))) d.gyro_file = imu;
  return d;
}

std::string Dataset::assumptions() const {
  if (timestamps_from_file || calibration.sensor.readout_s == 0.0) return {};
  return (root / "timestamps.txt").string() +
         " is missing: the rolling-shutter model (sensor.readout_s " +
         std::to_string(calibration.sensor.readout_s) + " s) takes the frames as " +
         std::to_string(static_cast<int>(kDefaultFps)) + " fps, 1/" +
         std::to_string(static_cast<int>(kDefaultFps)) + " s apart";
}

Expected<void> readFrame(const fs::path& path, cv::Size expected_size,
                         std::vector<std::uint8_t>& buffer, cv::Mat& out) {
  ImageLimits limits;
  limits.exact_size = expected_size;
  if (Expected<void> read = readImage(path, ImageColour::kAsStored, limits, buffer, out); !read)
    return read;
  if (out.depth() != CV_8U) {
    return fail(ErrorCode::kBadFrame, "%s: %d-bit image, expected 8-bit", path.c_str(),
                out.depth() == CV_16U ? 16 : 32);
  }
  return {};
}

Expected<cv::Mat> readFrame(const fs::path& path, cv::Size expected_size) {
  std::vector<std::uint8_t> buffer;
  cv::Mat image;
  if (Expected<void> read = readFrame(path, expected_size, buffer, image); !read)
    return std::unexpected(read.error());
  return image;
}

}  // namespace omnipose
