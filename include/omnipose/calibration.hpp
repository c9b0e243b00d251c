#pragma once
/// \file calibration.hpp
/// Lens and panorama geometry: the one place that knows how an omni-image pixel, a
/// panorama pixel and a bearing vector relate (DESIGN.md sections 2 and 6).
///
/// Panorama (W x H pixels, square, gamma = 2*pi/W radians per pixel):
///   azimuth  theta(u) = gamma * (u - u0)          counter-clockwise seen from above, u0 = +x
///   height   h(v)     = gamma * (v_h - v)         on the unit-radius cylinder, up positive
///   bearing           = normalize(cos theta, sin theta, h)   camera frame: x fwd, y left, z up
/// Integer (u, v) are pixel centres.
///
/// Omni image (donut): image angle a = atan2(y - cy, x - cx) (y down, so a grows clockwise
/// on screen), a = azimuth_zero + theta (cw) or azimuth_zero - theta (ccw). Radius maps
/// linearly to row: outer_edge top: r(v) = r_out - (v + 0.5) * (r_out - r_in) / H.

#include <Eigen/Core>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace omnipose {

/// How the azimuth grows on screen in the omni image (a mirror flips it).
enum class AzimuthDirection { kCw, kCcw };
/// Which panorama edge (top row 0 or bottom row H-1) the outer ring of the donut becomes.
enum class OuterEdge { kTop, kBottom };

/// The donut in the omni image. Lengths in pixels, angles in degrees.
struct OmniLens {
  int image_width = 720;
  int image_height = 720;
  double center_x = 359.5;        ///< mirror axis, pixel coordinates (x right)
  double center_y = 359.5;        ///< mirror axis, pixel coordinates (y down)
  double radius_inner = 120.0;    ///< used ring, pixels
  double radius_outer = 300.0;
  double azimuth_zero_deg = 0.0;  ///< image angle of the robot's +x axis
  AzimuthDirection azimuth_direction = AzimuthDirection::kCw;
  OuterEdge outer_edge = OuterEdge::kTop;
};

/// The unwrapped cylindrical panorama.
struct PanoramaGeometry {
  int width = 1100;              ///< W, pixels; gamma = 2*pi/W
  int height = 110;              ///< H, pixels
  double horizon_row = 54.5;     ///< v_h: row of the horizon (h = 0)
  double forward_column = 0.0;   ///< u0: column of the camera's +x axis

  /// Radians per pixel, 2*pi/W.
  double gamma() const;
  /// Azimuth of column u, radians (not wrapped).
  double azimuth(double u) const { return gamma() * (u - forward_column); }
  /// Column of azimuth theta (radians), wrapped into [0, W).
  double column(double theta) const;
  /// Cylinder height of row v (unit radius).
  double cylinderHeight(double v) const { return gamma() * (horizon_row - v); }
  /// Row of cylinder height h.
  double row(double h) const { return horizon_row - h / gamma(); }
  /// Unit bearing of panorama pixel (u, v) in the camera frame.
  Eigen::Vector3d bearing(double u, double v) const;
};

/// Thrown by Calibration::load / validate at start-up; what() lists every problem, one
/// per line, each naming the file and the field.
class CalibrationError : public std::runtime_error {
 public:
  CalibrationError(const std::string& what, std::vector<std::string> problems)
      : std::runtime_error(what), problems_(std::move(problems)) {}
  const std::vector<std::string>& problems() const { return problems_; }

 private:
  std::vector<std::string> problems_;
};

/// calibration.yaml: the lens and the panorama it is unwrapped to.
struct Calibration {
  OmniLens omni;
  PanoramaGeometry panorama;

  /// Every inconsistency, one message per bad field (empty = valid): sizes > 0, radii
  /// 0 <= r_in < r_out, centre inside the image, horizon inside the panorama, ...
  std::vector<std::string> validate() const;

  /// Reads a plain-YAML calibration file (DESIGN.md section 6). Missing sections/keys,
  /// wrong types, unknown keys and invalid values are all collected; throws
  /// CalibrationError listing every one of them, prefixed by the path.
  static Calibration load(const std::filesystem::path& path);
  /// Parses YAML text; `origin` names the source in error messages.
  static Calibration parse(const std::string& yaml_text, const std::string& origin = "<string>");
  /// Writes the file (plain YAML, same layout load() reads). Throws std::runtime_error
  /// naming the path when it cannot be written.
  void save(const std::filesystem::path& path) const;
  /// The YAML text save() writes.
  std::string toYaml() const;

  /// Omni-image pixel coordinates (x right, y down) seen by panorama pixel (u, v).
  Eigen::Vector2d omniPixel(double u, double v) const;
  /// Inverse of omniPixel: panorama (u, v) of omni pixel (x, y); u wrapped into [0, W).
  /// Meaningful only inside the used ring.
  Eigen::Vector2d panoramaPixel(double x, double y) const;
  /// Radius in the omni image (pixels) of panorama row v.
  double radiusOfRow(double v) const;
};

}  // namespace omnipose
