#include "omnipose/io/trajectory.hpp"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>
#include <stdexcept>

namespace omnipose {

std::vector<StampedPose> readTum(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error(path.string() + ": cannot open TUM trajectory");
  std::vector<StampedPose> poses;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    std::istringstream fields(line);
    double v[8];
    for (double& x : v) {
      if (!(fields >> x)) {
        throw std::runtime_error(path.string() + ":" + std::to_string(line_no) +
                                 ": expected 'timestamp tx ty tz qx qy qz qw'");
      }
    }
    for (const double x : v) {
      if (!std::isfinite(x)) {
        throw std::runtime_error(path.string() + ":" + std::to_string(line_no) +
                                 ": every value must be a finite number");
      }
    }
    Eigen::Quaterniond q(v[7], v[4], v[5], v[6]);
    if (!(std::abs(q.norm() - 1.0) <= 1e-3)) {
      throw std::runtime_error(path.string() + ":" + std::to_string(line_no) +
                               ": quaternion is not unit length");
    }
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
