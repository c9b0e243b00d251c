#include <cmath>
#include <numbers>

#include "omnipose/so3.hpp"
#include "omnipose/synth/synth.hpp"
#include "synth/equirect.hpp"

namespace omnipose::synth {
namespace {

// Lens body outside the used ring (grey levels): a dark centre showing a faint reflection
// of the phone camera, a dark housing just outside the ring, black beyond.
constexpr float kCentreGrey = 14.0f;
constexpr float kReflectionGrey = 45.0f;      ///< added at the very centre
constexpr double kReflectionRadius = 0.3;     ///< 1/e radius, fraction of radius_inner
constexpr float kHousingGrey = 24.0f;
constexpr double kHousingRadius = 1.12;       ///< outer edge of the housing, x radius_outer
constexpr float kOutsideGrey = 6.0f;

std::string joinLines(const std::vector<std::string>& lines) {
  std::string out;
  for (const auto& l : lines) out += "\n  " + l;
  return out;
}

/// Angle between two non-zero vectors, radians (atan2 form: accurate for small angles).
double angleBetween(const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  return std::atan2(a.cross(b).norm(), a.dot(b));
}

/// Grey level of the lens body at distance r (pixels) from the mirror axis.
float lensBody(const OmniLens& lens, double r) {
  if (r < lens.radius_inner) {
    const double s = r / (kReflectionRadius * lens.radius_inner);
    return kCentreGrey + kReflectionGrey * static_cast<float>(std::exp(-s * s));
  }
  return r < kHousingRadius * lens.radius_outer ? kHousingGrey : kOutsideGrey;
}

}  // namespace

std::vector<std::string> RenderOptions::validate() const {
  std::vector<std::string> p;
  if (supersample < 1 || supersample > 16) p.push_back("supersample: must be in [1, 16]");
  return p;
}

OutputKind parseOutputKind(const std::string& name) {
  if (name == "omni") return OutputKind::kOmni;
  if (name == "panorama") return OutputKind::kPanorama;
  throw std::invalid_argument("output '" + name + "' is not omni or panorama");
}

const char* toString(OutputKind kind) { return kind == OutputKind::kOmni ? "omni" : "panorama"; }

Renderer::Renderer(Scene scene, Calibration calibration, RenderOptions options)
    : scene_(std::move(scene)), calibration_(std::move(calibration)), options_(options) {
  std::vector<std::string> problems = options_.validate();
  for (const auto& p : calibration_.validate()) problems.push_back("calibration: " + p);
  if (scene_.texture.empty() || scene_.texture.type() != CV_32FC1) {
    problems.push_back("scene.texture: must be a non-empty CV_32FC1 image");
  }
  if (!problems.empty()) throw std::invalid_argument("Renderer:" + joinLines(problems));
  pyramid_ = detail::buildPyramid(scene_.texture);
}

cv::Size Renderer::outputSize() const {
  if (options_.output == OutputKind::kPanorama) {
    return calibration_.panorama.size();
  }
  return {calibration_.omni.image_width, calibration_.omni.image_height};
}

cv::Mat Renderer::render(const Eigen::Isometry3d& T_world_camera) const {
  if (scene_.kind == SceneKind::kBox && !scene_.box.contains(T_world_camera.translation())) {
    throw std::invalid_argument("Renderer::render: the camera is outside the box room");
  }
  cv::Mat out(outputSize(), CV_32FC1);
  cv::parallel_for_(cv::Range(0, out.rows), [&](const cv::Range& rows) {
    renderRows(T_world_camera, rows.start, rows.end, out);
  });
  return out;
}

cv::Mat Renderer::render(const std::function<Eigen::Isometry3d(double)>& pose_at,
                         double readout_s) const {
  cv::Mat out(outputSize(), CV_32FC1);
  std::vector<Eigen::Isometry3d> row_pose(static_cast<std::size_t>(out.rows));
  for (int y = 0; y < out.rows; ++y) {
    row_pose[static_cast<std::size_t>(y)] = pose_at(rowTime(y, out.rows, readout_s));
    if (scene_.kind == SceneKind::kBox &&
        !scene_.box.contains(row_pose[static_cast<std::size_t>(y)].translation()))
      throw std::invalid_argument("Renderer::render: the camera is outside the box room at row " +
                                  std::to_string(y));
  }
  cv::parallel_for_(cv::Range(0, out.rows), [&](const cv::Range& rows) {
    for (int y = rows.start; y < rows.end; ++y)
      renderRows(row_pose[static_cast<std::size_t>(y)], y, y + 1, out);
  });
  return out;
}

double rowTime(int y, int rows, double readout_s) {
  if (readout_s >= 0.0) return readout_s * y / rows;
  return -readout_s * (rows - 1 - y) / rows;
}

Eigen::Isometry3d poseBetween(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double s) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = a.linear() * rotationFromVector(s * rotationVector(a.linear().transpose() * b.linear()));
  T.translation() = a.translation() + s * (b.translation() - a.translation());
  return T;
}

Eigen::Isometry3d poseAtTime(std::span<const StampedPose> trajectory, double t) {
  if (trajectory.empty()) throw std::invalid_argument("poseAtTime: empty trajectory");
  if (trajectory.size() == 1) return trajectory.front().pose;
  // The step [k, k + 1] containing t (the first or last step outside the samples).
  std::size_t k = 0;
  while (k + 2 < trajectory.size() && trajectory[k + 1].timestamp <= t) ++k;
  const StampedPose& a = trajectory[k];
  const StampedPose& b = trajectory[k + 1];
  return poseBetween(a.pose, b.pose, (t - a.timestamp) / (b.timestamp - a.timestamp));
}

void Renderer::renderRows(const Eigen::Isometry3d& T, int row_begin, int row_end,
                          cv::Mat& out) const {
  const bool omni = options_.output == OutputKind::kOmni;
  for (int y = row_begin; y < row_end; ++y) {
    float* row = out.ptr<float>(y);
    for (int x = 0; x < out.cols; ++x) {
      row[x] = omni ? renderOmniPixel(T, x, y) : renderPanoramaPixel(T, x, y);
    }
  }
}

Eigen::Vector3d Renderer::textureDirection(const Eigen::Isometry3d& T,
                                           const Eigen::Vector3d& bearing) const {
  return scene_.textureDirection(T.translation(), T.linear() * bearing);
}

double Renderer::levelOfDetail(const Eigen::Vector3d& centre, const Eigen::Vector3d& right,
                               const Eigen::Vector3d& below) const {
  // Sub-sample footprint on the texture, in texels of level 0, as a mip level.
  const double footprint = std::max(angleBetween(centre, right), angleBetween(centre, below)) /
                           options_.supersample;
  return std::log2(footprint / detail::texelAngle(pyramid_));
}

float Renderer::renderPanoramaPixel(const Eigen::Isometry3d& T, int u, int v) const {
  const PanoramaGeometry& pano = calibration_.panorama;
  const double lod = levelOfDetail(textureDirection(T, pano.bearing(u, v)),
                                   textureDirection(T, pano.bearing(u + 1, v)),
                                   textureDirection(T, pano.bearing(u, v + 1)));
  // Box filter: mean over a K x K grid of sub-pixel centres.
  const int k = options_.supersample;
  double sum = 0.0;
  for (int j = 0; j < k; ++j) {
    const double sv = v + (j + 0.5) / k - 0.5;
    for (int i = 0; i < k; ++i) {
      const double su = u + (i + 0.5) / k - 0.5;
      sum += detail::sampleEquirect(pyramid_, textureDirection(T, pano.bearing(su, sv)), lod);
    }
  }
  return static_cast<float>(sum / (k * k));
}

float Renderer::renderOmniPixel(const Eigen::Isometry3d& T, int x, int y) const {
  const OmniLens& lens = calibration_.omni;
  // Rays through the used ring [radius_inner, radius_outer] (in the lens model's radius)
  // see the scene along the bearing the calibration assigns to them; the rest is the lens
  // body. Any lens model: the bearing comes from Calibration::bearingOfPixel.
  const auto inRing = [&](double px, double py) {
    const double r = calibration_.ringRadius(px, py);
    return r >= lens.radius_inner && r <= lens.radius_outer;
  };
  const auto bearingAt = [&](double px, double py) {
    const auto b = calibration_.bearingOfPixel(px, py);
    return b ? *b : Eigen::Vector3d(1, 0, 0);
  };
  const double r_centre = calibration_.ringRadius(x, y);
  const bool touches_ring =
      r_centre > lens.radius_inner - 1.5 && r_centre < lens.radius_outer + 1.5;
  const double lod = touches_ring ? levelOfDetail(textureDirection(T, bearingAt(x, y)),
                                                  textureDirection(T, bearingAt(x + 1, y)),
                                                  textureDirection(T, bearingAt(x, y + 1)))
                                  : 0.0;
  // Box filter: mean over a K x K grid of sub-pixel centres.
  const int k = options_.supersample;
  double sum = 0.0;
  for (int j = 0; j < k; ++j) {
    const double sy = y + (j + 0.5) / k - 0.5;
    for (int i = 0; i < k; ++i) {
      const double sx = x + (i + 0.5) / k - 0.5;
      const auto b = touches_ring && inRing(sx, sy) ? calibration_.bearingOfPixel(sx, sy)
                                                    : std::nullopt;
      sum += b ? detail::sampleEquirect(pyramid_, textureDirection(T, *b), lod)
               : lensBody(lens, calibration_.ringRadius(sx, sy));
    }
  }
  return static_cast<float>(sum / (k * k));
}

}  // namespace omnipose::synth
