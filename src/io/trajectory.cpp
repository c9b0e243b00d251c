#include "omnipose/io/trajectory.hpp"

#include "io/text_records.hpp"
#include "omnipose/file_io.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <optional>
#include <stdexcept>

namespace omnipose {

std::vector<StampedPose> readTum(const std::filesystem::path& path) {
  const std::string text = readTextFileOrThrow(path);
  std::vector<StampedPose> poses;
  for (const io::TextRecord& r : io::splitRecords(text)) {
    const std::string where = path.string() + ":" + std::to_string(r.line) + ": ";
    if (r.fields.size() < 8)
      throw std::runtime_error(where + "expected 'timestamp tx ty tz qx qy qz qw'");
    double v[8];
    for (int i = 0; i < 8; ++i) {
      const std::optional<double> x = io::parseDecimal(r.fields[static_cast<std::size_t>(i)]);
      if (!x || !std::isfinite(*x))
        throw std::runtime_error(where + "every value must be a finite decimal number");
      v[i] = *x;
    }
    Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
    if (!(std::abs(q.norm() - 1.0) <= 1e-3))
      throw std::runtime_error(where + "quaternion is not unit length");
    StampedPose p;
    p.timestamp = v[0];
    p.pose.linear() = q.normalized().toRotationMatrix();
    p.pose.translation() = Eigen::Vector3d(v[1], v[2], v[3]);
    poses.push_back(p);
  }
  return poses;
}

std::string formatTumLine(const StampedPose& p) {
  const Eigen::Quaterniond q(p.pose.rotation());
  const Eigen::Vector3d& t = p.pose.translation();
  char buf[256];
  std::snprintf(buf, sizeof(buf), "%.6f %.9g %.9g %.9g %.9g %.9g %.9g %.9g", p.timestamp, t.x(),
                t.y(), t.z(), q.x(), q.y(), q.z(), q.w());
  return buf;
}

void writeTum(const std::filesystem::path& path, const std::vector<StampedPose>& poses) {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path.string() + ": cannot write TUM trajectory");
  out << "# timestamp tx ty tz qx qy qz qw\n";
  for (const auto& p : poses) out << formatTumLine(p) << '\n';
  if (!out) throw std::runtime_error(path.string() + ": write failed");
}

}  // namespace omnipose
