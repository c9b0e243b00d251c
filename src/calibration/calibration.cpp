#include "omnipose/calibration.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <numbers>
#include <set>
#include <sstream>

namespace omnipose {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDegToRad = kPi / 180.0;

/// Collects every problem of a YAML document instead of stopping at the first.
class YamlReader {
 public:
  explicit YamlReader(std::string origin) : origin_(std::move(origin)) {}

  void problem(const std::string& key, const std::string& what) {
    problems_.push_back(origin_ + ": " + key + ": " + what);
  }
  std::vector<std::string>& problems() { return problems_; }

  /// Section `name` of `root` as a map; reports unknown keys against `known`.
  YAML::Node section(const YAML::Node& root, const std::string& name,
                     const std::set<std::string>& known) {
    const YAML::Node node = root[name];
    if (!node) {
      problem(name, "missing section");
      return {};
    }
    if (!node.IsMap()) {
      problem(name, "must be a map");
      return {};
    }
    for (const auto& kv : node) {
      const auto key = kv.first.as<std::string>();
      if (!known.contains(key)) problem(name + "." + key, "unknown key");
    }
    return node;
  }

  template <typename T>
  void read(const YAML::Node& section, const std::string& section_name, const std::string& key,
            T& value, bool required = true) {
    if (!section) return;
    const YAML::Node node = section[key];
    if (!node) {
      if (required) problem(section_name + "." + key, "missing");
      return;
    }
    try {
      value = node.as<T>();
    } catch (const YAML::Exception&) {
      problem(section_name + "." + key, "cannot read '" + YAML::Dump(node) + "' as " + typeName<T>());
    }
  }

 private:
  template <typename T>
  static const char* typeName() {
    if constexpr (std::is_same_v<T, int>) return "an integer";
    if constexpr (std::is_same_v<T, double>) return "a number";
    if constexpr (std::is_same_v<T, std::string>) return "a string";
    return "the expected type";
  }

  std::string origin_;
  std::vector<std::string> problems_;
};

std::string join(const std::vector<std::string>& lines) {
  std::string out;
  for (const auto& l : lines) out += "\n  " + l;
  return out;
}

}  // namespace

double PanoramaGeometry::gamma() const { return 2.0 * kPi / width; }

double PanoramaGeometry::column(double theta) const {
  double u = forward_column + theta / gamma();
  u = std::fmod(u, static_cast<double>(width));
  return u < 0 ? u + width : u;
}

Eigen::Vector3d PanoramaGeometry::bearing(double u, double v) const {
  const double theta = azimuth(u);
  return Eigen::Vector3d(std::cos(theta), std::sin(theta), cylinderHeight(v)).normalized();
}

std::vector<std::string> Calibration::validate() const {
  std::vector<std::string> p;
  const auto& o = omni;
  if (o.image_width <= 0) p.push_back("omni.image_width: must be > 0");
  if (o.image_height <= 0) p.push_back("omni.image_height: must be > 0");
  if (!(o.center_x >= 0 && o.center_x <= o.image_width - 1))
    p.push_back("omni.center: x = " + std::to_string(o.center_x) + " is outside the image width " +
                std::to_string(o.image_width));
  if (!(o.center_y >= 0 && o.center_y <= o.image_height - 1))
    p.push_back("omni.center: y = " + std::to_string(o.center_y) + " is outside the image height " +
                std::to_string(o.image_height));
  if (!(o.radius_inner >= 0)) p.push_back("omni.radius_inner: must be >= 0");
  if (!(o.radius_outer > o.radius_inner))
    p.push_back("omni.radius_outer: must be greater than radius_inner (" +
                std::to_string(o.radius_outer) + " <= " + std::to_string(o.radius_inner) + ")");
  if (!std::isfinite(o.azimuth_zero_deg)) p.push_back("omni.azimuth_zero_deg: must be finite");
  const auto& q = panorama;
  if (q.width <= 0) p.push_back("panorama.width: must be > 0");
  if (q.height <= 0) p.push_back("panorama.height: must be > 0");
  if (!(q.horizon_row >= -0.5 && q.horizon_row <= q.height - 0.5))
    p.push_back("panorama.horizon_row: " + std::to_string(q.horizon_row) +
                " is outside the panorama rows [-0.5, " + std::to_string(q.height - 0.5) + "]");
  if (!(q.forward_column >= 0 && q.forward_column < q.width))
    p.push_back("panorama.forward_column: must be in [0, width)");
  return p;
}

Calibration Calibration::parse(const std::string& text, const std::string& origin) {
  YamlReader r(origin);
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw CalibrationError(origin + ": not valid YAML: " + e.what(), {origin + ": " + e.what()});
  }
  Calibration c;
  if (!root || !root.IsMap()) {
    r.problem("(document)", "expected a map with sections 'omni' and 'panorama'");
  } else {
    for (const auto& kv : root) {
      const auto key = kv.first.as<std::string>();
      if (key != "omni" && key != "panorama") r.problem(key, "unknown section");
    }
    const YAML::Node omni = r.section(
        root, "omni",
        {"image_width", "image_height", "center", "radius_inner", "radius_outer",
         "azimuth_zero_deg", "azimuth_direction", "outer_edge"});
    r.read(omni, "omni", "image_width", c.omni.image_width);
    r.read(omni, "omni", "image_height", c.omni.image_height);
    if (omni) {
      const YAML::Node center = omni["center"];
      if (!center) {
        r.problem("omni.center", "missing");
      } else if (!center.IsSequence() || center.size() != 2) {
        r.problem("omni.center", "must be a list [x, y]");
      } else {
        try {
          c.omni.center_x = center[0].as<double>();
          c.omni.center_y = center[1].as<double>();
        } catch (const YAML::Exception&) {
          r.problem("omni.center", "must hold two numbers");
        }
      }
    }
    r.read(omni, "omni", "radius_inner", c.omni.radius_inner);
    r.read(omni, "omni", "radius_outer", c.omni.radius_outer);
    r.read(omni, "omni", "azimuth_zero_deg", c.omni.azimuth_zero_deg, false);
    std::string direction = "cw", edge = "top";
    r.read(omni, "omni", "azimuth_direction", direction, false);
    r.read(omni, "omni", "outer_edge", edge, false);
    if (direction == "cw") c.omni.azimuth_direction = AzimuthDirection::kCw;
    else if (direction == "ccw") c.omni.azimuth_direction = AzimuthDirection::kCcw;
    else r.problem("omni.azimuth_direction", "'" + direction + "' is not cw or ccw");
    if (edge == "top") c.omni.outer_edge = OuterEdge::kTop;
    else if (edge == "bottom") c.omni.outer_edge = OuterEdge::kBottom;
    else r.problem("omni.outer_edge", "'" + edge + "' is not top or bottom");

    const YAML::Node pano =
        r.section(root, "panorama", {"width", "height", "horizon_row", "forward_column"});
    r.read(pano, "panorama", "width", c.panorama.width);
    r.read(pano, "panorama", "height", c.panorama.height);
    c.panorama.horizon_row = 0.5 * c.panorama.height - 0.5;  // default: the middle
    r.read(pano, "panorama", "horizon_row", c.panorama.horizon_row, false);
    r.read(pano, "panorama", "forward_column", c.panorama.forward_column, false);
  }
  // Range checks only make sense on values that were read.
  if (r.problems().empty()) {
    for (const auto& p : c.validate()) r.problems().push_back(origin + ": " + p);
  }
  if (!r.problems().empty()) {
    throw CalibrationError(origin + ": invalid calibration:" + join(r.problems()), r.problems());
  }
  return c;
}

Calibration Calibration::load(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in) {
    throw CalibrationError(path.string() + ": cannot open calibration file",
                           {path.string() + ": cannot open calibration file"});
  }
  std::stringstream ss;
  ss << in.rdbuf();
  return parse(ss.str(), path.string());
}

std::string Calibration::toYaml() const {
  std::ostringstream o;
  o.precision(10);
  o << "omni:\n"
    << "  image_width: " << omni.image_width << "\n"
    << "  image_height: " << omni.image_height << "\n"
    << "  center: [" << omni.center_x << ", " << omni.center_y << "]\n"
    << "  radius_inner: " << omni.radius_inner << "\n"
    << "  radius_outer: " << omni.radius_outer << "\n"
    << "  azimuth_zero_deg: " << omni.azimuth_zero_deg << "\n"
    << "  azimuth_direction: " << (omni.azimuth_direction == AzimuthDirection::kCw ? "cw" : "ccw")
    << "\n"
    << "  outer_edge: " << (omni.outer_edge == OuterEdge::kTop ? "top" : "bottom") << "\n"
    << "panorama:\n"
    << "  width: " << panorama.width << "\n"
    << "  height: " << panorama.height << "\n"
    << "  horizon_row: " << panorama.horizon_row << "\n"
    << "  forward_column: " << panorama.forward_column << "\n";
  return o.str();
}

void Calibration::save(const std::filesystem::path& path) const {
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path.string() + ": cannot write calibration file");
  out << toYaml();
  if (!out) throw std::runtime_error(path.string() + ": write failed");
}

double Calibration::radiusOfRow(double v) const {
  const double step = (omni.radius_outer - omni.radius_inner) / panorama.height;
  return omni.outer_edge == OuterEdge::kTop ? omni.radius_outer - (v + 0.5) * step
                                            : omni.radius_inner + (v + 0.5) * step;
}

Eigen::Vector2d Calibration::omniPixel(double u, double v) const {
  const double theta = panorama.azimuth(u);
  const double sign = omni.azimuth_direction == AzimuthDirection::kCw ? 1.0 : -1.0;
  const double a = omni.azimuth_zero_deg * kDegToRad + sign * theta;
  const double r = radiusOfRow(v);
  return {omni.center_x + r * std::cos(a), omni.center_y + r * std::sin(a)};
}

Eigen::Vector2d Calibration::panoramaPixel(double x, double y) const {
  const double dx = x - omni.center_x, dy = y - omni.center_y;
  const double a = std::atan2(dy, dx);
  const double sign = omni.azimuth_direction == AzimuthDirection::kCw ? 1.0 : -1.0;
  const double theta = sign * (a - omni.azimuth_zero_deg * kDegToRad);
  const double r = std::hypot(dx, dy);
  const double step = (omni.radius_outer - omni.radius_inner) / panorama.height;
  const double v = omni.outer_edge == OuterEdge::kTop ? (omni.radius_outer - r) / step - 0.5
                                                      : (r - omni.radius_inner) / step - 0.5;
  return {panorama.column(theta), v};
}

}  // namespace omnipose
