#pragma once
/// \file lens_model.hpp
/// Non-linear catadioptric lens models: image pixel <-> (image angle, elevation), both
/// directions in one place per model. Calibration (calibration.hpp) combines them with the
/// robot's azimuth keys into bearings; the unwrap table, the renderer, the calibration tool
/// and the tests all go through it.
///
/// Every model here describes the lens by two numbers per pixel:
///   image angle  a = atan2(y - cy, x - cx) in the model's ideal (distortion-free) image
///                  coordinates (x right, y down, radians; y down so a grows clockwise)
///   elevation    e = angle above the horizontal plane of the robot (radians, up positive)
/// The robot's azimuth is derived from `a` by OmniLens::azimuth_zero_deg / direction.
///
/// Pixel coordinates: x = column, y = row, pixel centres at integers, of the frames the
/// camera delivers (the full frame, after any crop recorded in the calibration file).

#include <Eigen/Core>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace omnipose {

/// Image angle and elevation of one pixel (radians).
struct LensDirection {
  double image_angle = 0.0;  ///< a, radians, atan2(y, x) in ideal image coordinates
  double elevation = 0.0;    ///< e, radians above the robot's horizontal plane
  double radius = 0.0;       ///< distance from the axis in ideal image coordinates, pixels
};

/// Scaramuzza's OCamCalib model, exactly as its cam2world / world2cam define it
/// (calib_results.txt):
///   ideal (row, col) offsets  [xp; yp] = A^-1 [row - xc; col - yc],  A = [[c, d], [e, 1]]
///   rho = hypot(xp, yp);  camera ray (xp, yp, f(rho)),  f(rho) = ss0 + ss1 rho + ss2 rho^2 ...
///   world2cam: rho = invpol(theta), theta = atan(z / hypot(x, y)), pixel = A [xp; yp] + c
/// +z of OCamCalib's camera frame is the robot's up (camera under the mirror, looking up),
/// so the elevation of a pixel is atan2(f(rho), rho); image angle a = atan2(xp, yp) (row
/// offset is y, column offset is x).
/// world2cam here starts at the inverse polynomial and refines rho by Newton's method on
/// the direct polynomial, so both directions agree to 1e-9 px (OCamCalib's invpol is a
/// least-squares fit of the inverse; how far it is off is reported by invpolMaxErrorPx()).
struct OcamCalibModel {
  std::vector<double> ss;       ///< direct polynomial f(rho), coefficients of rho^0, rho^1, ...
  std::vector<double> invpol;   ///< inverse polynomial rho(theta), coefficients of theta^0, ...
  double xc = 0.0;              ///< centre row, pixels, in the frame (crop applied)
  double yc = 0.0;              ///< centre column, pixels, in the frame (crop applied)
  double c = 1.0, d = 0.0, e = 0.0;  ///< affine parameters
  int height = 0;               ///< frame height, pixels
  int width = 0;                ///< frame width, pixels (calibrated width + crops)
  std::optional<double> roi_max_radius;  ///< "ROI max min radius" line, when present
  std::optional<double> roi_min_radius;
  int crop_left = 0, crop_right = 0;     ///< "left right cropped pixel" line, when present
  int ss_line = 0;              ///< line of the file holding ss (for error messages)
  std::string origin;           ///< the file it came from
  std::string text;             ///< the file's text, as read (written back by save())

  /// Parses calib_results.txt text. Comment lines start with '#'; the data lines come in
  /// OCamCalib's order: ss, invpol, centre (row col), affine (c d e), image size
  /// (height width); then optionally, as pyomniunwarp writes them, "ROI max min radius"
  /// and "left right cropped pixel" (the calibration was made on a crop: frame columns =
  /// calibrated columns + left, frame width = width + left + right). Throws
  /// std::runtime_error "ORIGIN: line N: ..." naming every problem (truncated file,
  /// missing or extra numbers, non-finite values, degenerate affine matrix, sizes out of
  /// range).
  static OcamCalibModel parse(const std::string& text, const std::string& origin);
  /// Reads and parses a file; throws std::runtime_error naming the path when unreadable.
  static OcamCalibModel load(const std::filesystem::path& path);

  /// f(rho) of the direct polynomial.
  double f(double rho) const;
  /// Elevation of ideal radius rho: atan2(f(rho), rho), radians.
  double elevation(double rho) const;
  /// Ideal radius whose elevation is `elevation`: invpol start + Newton on the direct
  /// polynomial; nullopt when it does not converge inside [0, 2 * max(width, height)].
  std::optional<double> radius(double elevation) const;
  /// Pixel (x = column, y = row) -> image angle, elevation, radius.
  LensDirection direction(const Eigen::Vector2d& pixel) const;
  /// Image angle a and radius rho -> pixel (x = column, y = row).
  Eigen::Vector2d pixel(double image_angle, double rho) const;
  /// Largest |invpol(theta) - rho| over radii [r0, r1], pixels: how far OCamCalib's own
  /// world2cam would be from the direct polynomial there.
  double invpolMaxErrorPx(double r0, double r1) const;
};

/// OpenCV omnidir's unified (Mei) model: xi, K = [[fx, s, cx], [0, fy, cy], [0, 0, 1]],
/// D = (k1, k2, p1, p2), as cv::omnidir::calibrate returns them:
///   Xs = X / |X|;  (x, y) = (Xs_x, Xs_y) / (Xs_z + xi);  radial-tangential distortion;
///   u = fx x_d + s y_d + cx,  v = fy y_d + cy.
/// The centre of the image looks along +z of omnidir's frame, which for a camera under
/// the mirror looking up is straight down: the robot's up is -z, so the elevation of a
/// pixel is asin(-Xs_z) and its image angle atan2(Xs_y, Xs_x).
struct MeiModel {
  double xi = 1.0;
  double fx = 0.0, fy = 0.0, s = 0.0, cx = 0.0, cy = 0.0;
  double k1 = 0.0, k2 = 0.0, p1 = 0.0, p2 = 0.0;

  /// One message per bad value (empty = valid): finite, fx, fy > 0, xi >= 0.
  std::vector<std::string> validate() const;
  /// Reads xi, K and D from a cv::FileStorage file (YAML/XML/JSON) as cv::omnidir users
  /// save them: keys `xi` (number or 1x1 matrix), `K` or `camera_matrix` (3x3), `D` or
  /// `distortion_coefficients` (4 values). Throws std::runtime_error naming the file and
  /// the key.
  static MeiModel loadFileStorage(const std::filesystem::path& path);

  /// Unit vector on omnidir's sphere -> pixel; nullopt where the model cannot project
  /// (Xs_z + xi <= 0, or beyond the fold of the mirror when xi > 1).
  std::optional<Eigen::Vector2d> project(const Eigen::Vector3d& Xs) const;
  /// Pixel -> unit vector on omnidir's sphere (distortion removed by Newton's method);
  /// nullopt outside the model's image of the sphere.
  std::optional<Eigen::Vector3d> unproject(const Eigen::Vector2d& pixel) const;
  /// Pixel -> image angle, elevation and radius (distance from (cx, cy), pixels).
  std::optional<LensDirection> direction(const Eigen::Vector2d& pixel) const;
  /// Image angle and elevation -> pixel.
  std::optional<Eigen::Vector2d> pixel(double image_angle, double elevation) const;
};

}  // namespace omnipose
