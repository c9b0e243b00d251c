#pragma once
// Rendered omni images with a known calibration for the calibration-tool tests (the exact
// renderer of omnipose::synth), cached per process because rendering is the slow part.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <numbers>
#include <opencv2/core.hpp>
#include <string>
#include <tuple>

#include "omnipose/calibration.hpp"
#include "omnipose/io/trajectory.hpp"
#include "omnipose/synth/synth.hpp"

namespace omnipose::calibrate::testing {

inline const std::filesystem::path kSourceDir = OMNIPOSE_SOURCE_DIR;
inline const std::filesystem::path kSharedData = kSourceDir / ".." / "shared" / "data";
/// In the repository (MIT licence beside it).
inline const std::filesystem::path kIndoor = kSourceDir / "tests/data/equirect/indoor_1024x512.jpg";
/// Only in the shared data folder (tests using it skip when it is absent).
inline const std::filesystem::path kPark = kSharedData / "equirect/park_theta_v_5376x2688.jpg";

/// A calibration with the given lens; panorama 1100 x `height` (the paper's W; a taller H
/// widens the vertical field of view: +-H/2 * 2 pi / W radians of cylinder height).
inline Calibration makeCalibration(int width, int height, double cx, double cy, double r_in,
                                   double r_out, double azimuth_zero_deg, AzimuthDirection dir,
                                   OuterEdge edge, int pano_height = 110) {
  Calibration c;
  c.omni.image_width = width;
  c.omni.image_height = height;
  c.omni.center_x = cx;
  c.omni.center_y = cy;
  c.omni.radius_inner = r_in;
  c.omni.radius_outer = r_out;
  c.omni.azimuth_zero_deg = azimuth_zero_deg;
  c.omni.azimuth_direction = dir;
  c.omni.outer_edge = edge;
  c.panorama.width = 1100;
  c.panorama.height = pano_height;
  c.panorama.horizon_row = 0.5 * pano_height - 0.5;
  return c;
}

/// Camera pose turned left (counter-clockwise seen from above) by `yaw_deg` from the start.
inline Eigen::Isometry3d yawPose(double yaw_deg) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = rotationFromVector(Eigen::Vector3d(0, 0, yaw_deg * std::numbers::pi / 180.0));
  return T;
}

/// The 8-bit omni image of a sphere scene textured with `texture`, seen at `yaw_deg`, 2 x 2
/// rays per pixel (the ring's edges are then found as closely as at 3 x 3: within 0.03 px).
/// `noise`/`blur`: sensor degradations (grey levels / pixels).
inline cv::Mat renderOmni(const std::filesystem::path& texture, const Calibration& cal,
                          double yaw_deg, double noise = 0.0, double blur = 0.0) {
  using Key = std::tuple<std::string, std::string, double, double, double>;
  static std::map<Key, cv::Mat> cache;
  static std::map<std::string, synth::Scene> scenes;
  const Key key{texture.string(), cal.toYaml(), yaw_deg, noise, blur};
  if (auto it = cache.find(key); it != cache.end()) return it->second;
  auto sit = scenes.find(texture.string());
  if (sit == scenes.end())
    sit = scenes.emplace(texture.string(), synth::Scene::load(texture, synth::SceneKind::kSphere))
              .first;
  synth::RenderOptions options;
  options.supersample = 2;
  synth::Renderer renderer(sit->second, cal, options);
  synth::DegradeOptions d;
  d.noise_sigma = noise;
  d.blur_sigma = blur;
  d.seed = 7;
  cv::Mat img = synth::degrade(renderer.render(yawPose(yaw_deg)), d, 0);
  cache.emplace(key, img);
  return img;
}

}  // namespace omnipose::calibrate::testing
