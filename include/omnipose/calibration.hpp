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
/// on screen), a = azimuth_zero + theta (cw) or azimuth_zero - theta (ccw). The lens model
/// (`omni.model`) relates a pixel's radius to its elevation:
///   linear     radius maps linearly to panorama row: outer_edge top:
///              r(v) = r_out - (v + 0.5) * (r_out - r_in) / H (the panorama defines the lens)
///   ocamcalib  Scaramuzza's calib_results.txt (lens_model.hpp): elevation atan2(f(rho), rho)
///   mei        OpenCV omnidir's unified model (xi, K, D), robot up = -z of its frame
/// For every model the panorama is the same cylinder; for ocamcalib and mei each panorama
/// pixel's bearing goes through the model to an image pixel, and every panorama row must
/// lie inside the elevations of the used ring [radius_inner, radius_outer].
/// An optional mask (`omni.mask`, 8-bit, frame size, 0 = never use) marks what the lens
/// sees of the robot itself (mast, body, cables).

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cmath>
#include <filesystem>
#include <opencv2/core.hpp>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "omnipose/config_error.hpp"
#include "omnipose/lens_model.hpp"

namespace omnipose {

/// How the azimuth grows on screen in the omni image (a mirror flips it).
enum class AzimuthDirection { kCw, kCcw };
/// Which panorama edge (top row 0 or bottom row H-1) the outer ring of the donut becomes.
enum class OuterEdge { kTop, kBottom };
/// How image radius relates to elevation (`omni.model`).
enum class LensModelKind { kLinear, kOcamCalib, kMei };

/// "linear" | "ocamcalib" | "mei".
const char* toString(LensModelKind kind);
/// "cw" | "ccw" (the calibration file's omni.azimuth_direction).
const char* toString(AzimuthDirection direction);
/// "top" | "bottom" (the calibration file's omni.outer_edge).
const char* toString(OuterEdge edge);

/// The donut in the omni image. Lengths in pixels, angles in degrees.
/// For `ocamcalib` the image size and centre come from the OCamCalib file (the keys may be
/// left out; when given they must agree), the ring defaults to the file's ROI; for `mei`
/// the centre is K's principal point. Ring radii are measured in the model's ideal image
/// coordinates (ocamcalib: after its affine correction).
struct OmniLens {
  LensModelKind model = LensModelKind::kLinear;
  int image_width = 720;
  int image_height = 720;
  double center_x = 359.5;        ///< mirror axis, pixel coordinates (x right)
  double center_y = 359.5;        ///< mirror axis, pixel coordinates (y down)
  double radius_inner = 120.0;    ///< used ring, pixels
  double radius_outer = 300.0;
  double azimuth_zero_deg = 0.0;  ///< image angle of the robot's +x axis
  AzimuthDirection azimuth_direction = AzimuthDirection::kCw;
  OuterEdge outer_edge = OuterEdge::kTop;  ///< linear only (the others know their elevation)

  /// `ocamcalib`: the file as written in the YAML (relative to it) and its contents.
  std::string ocamcalib_file;
  std::optional<OcamCalibModel> ocamcalib;
  /// `mei`: the omnidir cv::FileStorage file as written in the YAML (empty when xi, K, D
  /// are given inline) and the model.
  std::string omnidir_file;
  std::optional<MeiModel> mei;
  /// Optional mask: the file as written in the YAML and the image (CV_8UC1, frame size;
  /// 0 = never use that pixel). Empty = every pixel is used.
  std::string mask_file;
  cv::Mat mask;
};

/// The unwrapped cylindrical panorama.
struct PanoramaGeometry {
  int width = 1100;              ///< W, pixels; gamma = 2*pi/W
  int height = 110;              ///< H, pixels
  double horizon_row = 54.5;     ///< v_h: row of the horizon (h = 0)
  double forward_column = 0.0;   ///< u0: column of the camera's +x axis

  /// W x H, pixels.
  cv::Size size() const { return {width, height}; }
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

/// Where in the exposure of the row read first a camera's timestamp falls (calibration.yaml
/// `sensor.timestamp`): the middle (omnipose's own convention: a frame's timestamp is its
/// first row's capture time), the start (Android's SENSOR_TIMESTAMP), or the end, when the
/// row's readout starts (a CSI-2 receiver's start-of-frame interrupt, as on a Raspberry Pi).
enum class StampedAt { kExposureMiddle, kExposureStart, kExposureEnd };
const char* toString(StampedAt at);

/// Row timing of the sensor (DESIGN.md section 2). A phone or Raspberry Pi camera reads its
/// rows out one after another (rolling shutter): row y of a frame of H rows is captured at
/// t + rowTime(y, H, readout_s), t being the frame's timestamp (the capture of the row read
/// first). A published pose is the camera's pose at t.
struct SensorTiming {
  /// Seconds from the first row read to the last row of the frame as delivered; 0 = a
  /// global shutter (default); negative = the last row is read first. |readout_s| at most
  /// kMaxReadoutS.
  double readout_s = 0.0;
  /// Seconds each row is exposed, centred on its capture time; 0 = not known (default).
  /// Only the gyro path reads it: a row exposed while the camera turns shows the mean of the
  /// poses over its exposure (motion blur), which it takes out with the gyro's rotation
  /// (DESIGN.md section 3, "Motion blur"). At most kMaxExposureS.
  double exposure_s = 0.0;
  /// Where the camera stamps a frame; the sources move each stamp to the first row's
  /// capture time (captureTimeOffset()).
  StampedAt stamped_at = StampedAt::kExposureMiddle;
  /// A frame's exposure, seconds: `stated_s`, as its camera reported it, or exposure_s when
  /// it reported none (NaN).
  double exposureOf(double stated_s) const { return std::isnan(stated_s) ? exposure_s : stated_s; }
  /// Seconds after the timestamp of a frame exposed for `exposure_s` seconds at which its
  /// last row's exposure ends: how far past the stamp the gyro's samples must reach.
  double exposureEndAfterStamp(double exposure_s) const {
    return std::abs(readout_s) + 0.5 * exposure_s;
  }
  /// Seconds to add to the stamp of a frame whose rows were exposed for `exposure_s`
  /// seconds to get its first row's capture time: 0, +exposure / 2 or -exposure / 2.
  double captureTimeOffset(double exposure_s) const {
    return stamped_at == StampedAt::kExposureStart ? 0.5 * exposure_s
           : stamped_at == StampedAt::kExposureEnd ? -0.5 * exposure_s
                                                   : 0.0;
  }
  static constexpr double kMaxReadoutS = 0.1;
  static constexpr double kMaxExposureS = 0.1;
};

/// The camera-gyro calibration (calibration.yaml section `imu`, DESIGN.md sections 2 and 6):
/// how the robot's gyro is mounted on the camera and how its clock relates to the frames'.
struct ImuCalibration {
  /// Camera from IMU: a rate w measured about the IMU's axes is rotation * w about the
  /// camera's (x forward, y left, z up). YAML `rotation: [w, x, y, z]`, of norm 1 within
  /// kUnitTolerance (normalised when read).
  Eigen::Quaterniond rotation = Eigen::Quaterniond::Identity();
  /// A sample stamped t on the IMU's clock was taken at camera time t + time_offset_s,
  /// seconds; |time_offset_s| at most kMaxTimeOffsetS.
  double time_offset_s = 0.0;
  /// White rate noise, rad/s/sqrt(Hz), > 0; unset when not known.
  std::optional<double> gyro_noise_density;

  static constexpr double kMaxTimeOffsetS = 1.0;
  static constexpr double kUnitTolerance = 1e-3;
};

/// Capture time of image row y (pixel centres at integers; fractional rows interpolate) of
/// a frame of `rows` rows, seconds after the frame's timestamp: readout_s * y / rows, or,
/// with a negative readout_s (last row first), |readout_s| * (rows - 1 - y) / rows. 0 for a
/// global shutter.
double rowTime(double y, int rows, double readout_s);

/// Thrown by Calibration::load / parse at start-up: the configuration error (problems()
/// lists every problem, each naming the file and the field).
using CalibrationError = ConfigError;

/// calibration.yaml: the lens and the panorama it is unwrapped to.
struct Calibration {
  OmniLens omni;
  PanoramaGeometry panorama;
  SensorTiming sensor;  ///< optional section `sensor` (global shutter when absent)
  std::optional<ImuCalibration> imu;  ///< optional section `imu` (no gyro when absent)

  /// Every inconsistency, one message per bad field (empty = valid): every number finite,
  /// sizes in (0, limits.hpp], radii 0 <= r_in < r_out, centre inside the image, horizon
  /// inside the panorama, the lens model's elevation monotonic over the ring, every
  /// panorama row inside the ring's elevations, the mask of the frame size,
  /// |sensor.readout_s| <= SensorTiming::kMaxReadoutS; imu.rotation a unit quaternion within
  /// ImuCalibration::kUnitTolerance, |imu.time_offset_s| <= kMaxTimeOffsetS,
  /// imu.gyro_noise_density > 0.
  std::vector<std::string> validate() const;

  /// Reads a plain-YAML calibration file (DESIGN.md section 6) and the files it names
  /// (OCamCalib, omnidir, mask; relative to the YAML). Missing sections/keys, wrong types,
  /// unknown keys and invalid values are all collected; throws CalibrationError listing
  /// every one of them, prefixed by the path (and the line, inside an OCamCalib file).
  static Calibration load(const std::filesystem::path& path);
  /// Parses YAML text; `origin` names the source in error messages; files it names are
  /// looked up relative to `base_dir` (default: the current directory).
  static Calibration parse(const std::string& yaml_text, const std::string& origin = "<string>",
                           const std::filesystem::path& base_dir = {});
  /// Writes the file (plain YAML, same layout load() reads) and, beside it, the files it
  /// names (the OCamCalib text as read, the mask as PNG). Throws std::runtime_error naming
  /// the path when it cannot be written.
  void save(const std::filesystem::path& path) const;
  /// The YAML text save() writes.
  std::string toYaml() const;

  /// Omni-image pixel coordinates (x right, y down) seen by panorama pixel (u, v);
  /// (NaN, NaN) where the lens model cannot see that bearing.
  Eigen::Vector2d omniPixel(double u, double v) const;
  /// Inverse of omniPixel: panorama (u, v) of omni pixel (x, y); u wrapped into [0, W).
  /// Meaningful only inside the used ring; (NaN, NaN) where the model has no bearing.
  Eigen::Vector2d panoramaPixel(double x, double y) const;
  /// Unit bearing (camera frame: x forward, y left, z up) seen by omni pixel (x, y);
  /// nullopt where the lens model has none.
  std::optional<Eigen::Vector3d> bearingOfPixel(double x, double y) const;
  /// Omni pixel that sees `bearing` (any length > 0); nullopt where the model cannot.
  std::optional<Eigen::Vector2d> pixelOfBearing(const Eigen::Vector3d& bearing) const;
  /// Radius of omni pixel (x, y) in the lens model's ideal image coordinates, pixels: the
  /// measure of radius_inner / radius_outer. Plain distance to the centre for linear.
  double ringRadius(double x, double y) const;
  /// Elevations (radians, up positive) at radius_inner and radius_outer.
  std::pair<double, double> ringElevations() const;
  /// Capture time of panorama pixel (u, v), seconds after the frame's timestamp: the
  /// rowTime() of the omni pixel it is unwrapped from; 0 for a global shutter; NaN where the
  /// lens model cannot see the pixel's bearing.
  double captureTime(double u, double v) const;
  /// Radius in the omni image (pixels) of panorama row v (linear model).
  double radiusOfRow(double v) const;
};

}  // namespace omnipose
