#pragma once
/// \file trajectory.hpp
/// Poses and the TUM trajectory format (`timestamp tx ty tz qx qy qz qw`, one pose per
/// line, '#' comments). A pose T maps camera coordinates to world coordinates
/// (P_world = R * P_cam + t). The relative pose of frame k w.r.t. k-1 is
/// inverse(T_{k-1}) * T_k (DESIGN.md section 2).

#include <Eigen/Geometry>
#include <filesystem>
#include <string>
#include <vector>

#include "omnipose/so3.hpp"  // rotationVector / rotationFromVector, kept for its users

namespace omnipose {

/// One timestamped pose.
struct StampedPose {
  double timestamp = 0.0;  ///< seconds
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
};

/// Reads a TUM file. Throws std::runtime_error naming the file and the line on a
/// malformed line or a non-unit quaternion (|q| off by more than 1e-3).
std::vector<StampedPose> readTum(const std::filesystem::path& path);
/// Writes a TUM file with full precision (timestamps %.6f, values %.9g). Throws
/// std::runtime_error naming the path when it cannot be written.
void writeTum(const std::filesystem::path& path, const std::vector<StampedPose>& poses);
/// One TUM line (no newline).
std::string formatTumLine(const StampedPose& pose);

}  // namespace omnipose
