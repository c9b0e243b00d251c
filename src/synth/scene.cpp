#include "omnipose/synth/scene.hpp"

#include <cmath>
#include <limits>
#include <opencv2/core.hpp>
#include <stdexcept>
#include <string>

#include "omnipose/image_decode.hpp"

namespace omnipose::synth {
namespace {

Eigen::AlignedBox3d bounds(const Box& b) {
  return {Eigen::Vector3d(-0.5 * b.length, -0.5 * b.width, b.floor),
          Eigen::Vector3d(0.5 * b.length, 0.5 * b.width, b.ceiling)};
}

/// Shrinks [lo, hi] by margin at both ends; collapses to the middle if it would invert.
void shrink(double& lo, double& hi, double margin) {
  if (hi - lo < 2.0 * margin) {
    lo = hi = 0.5 * (lo + hi);
  } else {
    lo += margin;
    hi -= margin;
  }
}

std::string joinLines(const std::vector<std::string>& lines) {
  std::string out;
  for (const auto& l : lines) out += "\n  " + l;
  return out;
}

}  // namespace

std::vector<std::string> Box::validate() const {
  std::vector<std::string> p;
  if (!(length > 0)) p.push_back("box.length: must be > 0");
  if (!(width > 0)) p.push_back("box.width: must be > 0");
  if (!(floor < 0)) p.push_back("box.floor: must be < 0 (the origin is inside the room)");
  if (!(ceiling > 0)) p.push_back("box.ceiling: must be > 0 (the origin is inside the room)");
  return p;
}

Eigen::AlignedBox3d Box::interior(double wall_margin, double floor_ceiling_margin) const {
  Eigen::AlignedBox3d r = bounds(*this);
  shrink(r.min().x(), r.max().x(), wall_margin);
  shrink(r.min().y(), r.max().y(), wall_margin);
  shrink(r.min().z(), r.max().z(), floor_ceiling_margin);
  return r;
}

bool Box::contains(const Eigen::Vector3d& p) const { return bounds(*this).contains(p); }

Scene Scene::load(const std::filesystem::path& photo, SceneKind kind, const Box& box) {
  if (!std::filesystem::is_regular_file(photo)) {
    throw std::runtime_error(photo.string() + ": texture image not found");
  }
  ImageLimits limits;
  limits.apply_exif_orientation = true;  // a photo, as a viewer shows it
  const Expected<cv::Mat> grey = readImage(photo, ImageColour::kGrey, limits);
  if (!grey) throw std::runtime_error("texture image " + std::string(grey.error().message()));
  if (const auto problems = box.validate(); !problems.empty()) {
    throw std::runtime_error("invalid box room:" + joinLines(problems));
  }
  Scene scene;
  grey->convertTo(scene.texture, CV_32FC1);
  scene.kind = kind;
  scene.box = box;
  return scene;
}

void turnTexture(Scene& scene, double turn_deg, bool mirrored) {
  if (!std::isfinite(turn_deg))
    throw std::invalid_argument("texture turn: " + std::to_string(turn_deg) + " is not finite");
  if (scene.texture.empty()) throw std::invalid_argument("texture turn: the texture is empty");
  if (mirrored) cv::flip(scene.texture, scene.texture, 1);
  const int cols = scene.texture.cols;
  const double turns = turn_deg / 360.0 - std::floor(turn_deg / 360.0);  // [0, 1)
  const int shift = static_cast<int>(std::lround(turns * cols)) % cols;
  if (shift == 0) return;
  cv::Mat turned;
  cv::hconcat(scene.texture.colRange(cols - shift, cols), scene.texture.colRange(0, cols - shift),
              turned);
  scene.texture = turned;
}

Eigen::Vector3d Scene::textureDirection(const Eigen::Vector3d& origin,
                                        const Eigen::Vector3d& direction) const {
  if (kind == SceneKind::kSphere) return direction;
  // Ray-box exit: the smallest positive distance to the three planes the ray heads for.
  const Eigen::AlignedBox3d b = bounds(box);
  double t = std::numeric_limits<double>::infinity();
  for (int i = 0; i < 3; ++i) {
    if (direction[i] > 0) t = std::min(t, (b.max()[i] - origin[i]) / direction[i]);
    if (direction[i] < 0) t = std::min(t, (b.min()[i] - origin[i]) / direction[i]);
  }
  return origin + t * direction;
}

SceneKind parseSceneKind(const std::string& name) {
  if (name == "sphere") return SceneKind::kSphere;
  if (name == "box") return SceneKind::kBox;
  throw std::invalid_argument("scene '" + name + "' is not sphere or box");
}

const char* toString(SceneKind kind) { return kind == SceneKind::kSphere ? "sphere" : "box"; }

}  // namespace omnipose::synth
