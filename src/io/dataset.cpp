#include "omnipose/io/dataset.hpp"

#include "omnipose/image_decode.hpp"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <map>
#include <sstream>
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

std::map<std::string, double> readTimestamps(const fs::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path.string() + ": cannot open");
  std::map<std::string, double> stamps;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream fields(line);
    std::string name;
    double t = 0;
    if (!(fields >> name >> t)) {
      throw std::runtime_error(path.string() + ":" + std::to_string(line_no) +
                               ": expected '<file name> <seconds>'");
    }
    // Finite and within +-1e10 s (year 2286): pacing converts to integer microseconds.
    if (!std::isfinite(t) || std::abs(t) > kMaxTimestamp) {
      throw std::runtime_error(path.string() + ":" + std::to_string(line_no) +
                               ": timestamp must be a finite number of seconds within +-1e10");
    }
    stamps[name] = t;
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
  if (fs::exists(stamps_path)) {
    const auto stamps = readTimestamps(stamps_path);
    for (auto& f : d.frames) {
      const auto it = stamps.find(f.path.filename().string());
      if (it == stamps.end()) {
        throw std::runtime_error(stamps_path.string() + ": no timestamp for frame " +
                                 f.path.filename().string());
      }
      f.timestamp = it->second;
    }
    d.timestamps_from_file = true;
  } else {
    for (std::size_t i = 0; i < d.frames.size(); ++i) d.frames[i].timestamp = i / kDefaultFps;
  }

  const fs::path gt_path = root / "groundtruth.tum";
  if (fs::exists(gt_path)) d.groundtruth = readTum(gt_path);
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
