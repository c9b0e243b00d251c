#include "omnipose/calibration.hpp"
#include "omnipose/file_io.hpp"

#include <yaml-cpp/yaml.h>

#include <cmath>
#include <fstream>
#include <limits>
#include <numbers>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "common/format.hpp"
#include "common/named_values.hpp"
#include "common/problem_list.hpp"
#include "common/yaml_reader.hpp"
#include "omnipose/image_decode.hpp"
#include "omnipose/limits.hpp"

namespace omnipose {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kDegToRad = kPi / 180.0;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

constexpr detail::Named<LensModelKind> kLensModels[] = {{LensModelKind::kLinear, "linear"},
                                                        {LensModelKind::kOcamCalib, "ocamcalib"},
                                                        {LensModelKind::kMei, "mei"}};
constexpr detail::Named<AzimuthDirection> kAzimuthDirections[] = {{AzimuthDirection::kCw, "cw"},
                                                                  {AzimuthDirection::kCcw, "ccw"}};
constexpr detail::Named<StampedAt> kStampedAt[] = {{StampedAt::kExposureMiddle, "exposure_middle"},
                                                   {StampedAt::kExposureStart, "exposure_start"},
                                                   {StampedAt::kExposureEnd, "exposure_end"}};
constexpr detail::Named<OuterEdge> kOuterEdges[] = {{OuterEdge::kTop, "top"},
                                                    {OuterEdge::kBottom, "bottom"}};

using detail::YamlReader;
using Need = YamlReader::Need;

std::string fixed(double v, int digits = 1) { return detail::fixed(v, digits); }

double deg(double rad) { return rad / kDegToRad; }

/// Panorama column of azimuth theta, rows of cylinder height h: the bearing's panorama pixel.
Eigen::Vector2d panoramaOfBearing(const PanoramaGeometry& pano, const Eigen::Vector3d& b) {
  const double horizontal = std::hypot(b.x(), b.y());
  if (!(horizontal > 0)) return {kNaN, kNaN};
  return {pano.column(std::atan2(b.y(), b.x())), pano.row(b.z() / horizontal)};
}

Eigen::Vector3d bearingOf(double theta, double elevation) {
  const double ce = std::cos(elevation);
  return {ce * std::cos(theta), ce * std::sin(theta), std::sin(elevation)};
}

}  // namespace

const char* toString(LensModelKind kind) { return detail::nameOf(kLensModels, kind); }
const char* toString(StampedAt at) { return detail::nameOf(kStampedAt, at); }
const char* toString(AzimuthDirection direction) {
  return detail::nameOf(kAzimuthDirections, direction);
}
const char* toString(OuterEdge edge) { return detail::nameOf(kOuterEdges, edge); }

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

// ---------------------------------------------------------------------------------------
// Validation
// ---------------------------------------------------------------------------------------

namespace {

/// The fields each on their own and against each other: sizes, the ring, the readout, the
/// panorama's rows and columns.
void checkFields(const Calibration& c, std::vector<std::string>& p) {
  const auto& o = c.omni;
  const auto size = [&](int v, int max, const char* name) {
    if (v < 1 || v > max)
      p.push_back(std::string(name) + ": " + std::to_string(v) + " must be in [1, " + std::to_string(max) + "]");
  };
  const auto finite = [&](double v, const char* name) {
    if (std::isfinite(v)) return true;
    p.push_back(std::string(name) + ": must be a finite number");
    return false;
  };
  size(o.image_width, limits::kMaxImageSide, "omni.image_width");
  size(o.image_height, limits::kMaxImageSide, "omni.image_height");
  if (finite(o.center_x, "omni.center") && finite(o.center_y, "omni.center")) {
    if (!(o.center_x >= 0 && o.center_x <= o.image_width - 1))
      p.push_back("omni.center: x = " + std::to_string(o.center_x) + " is outside the image width " +
                  std::to_string(o.image_width));
    if (!(o.center_y >= 0 && o.center_y <= o.image_height - 1))
      p.push_back("omni.center: y = " + std::to_string(o.center_y) + " is outside the image height " +
                  std::to_string(o.image_height));
  }
  if (finite(o.radius_inner, "omni.radius_inner") && !(o.radius_inner >= 0))
    p.push_back("omni.radius_inner: must be >= 0");
  if (finite(o.radius_outer, "omni.radius_outer") && std::isfinite(o.radius_inner)) {
    if (!(o.radius_outer > o.radius_inner))
      p.push_back("omni.radius_outer: must be greater than radius_inner (" +
                  std::to_string(o.radius_outer) + " <= " + std::to_string(o.radius_inner) + ")");
    else if (o.radius_outer > 2.0 * limits::kMaxImageSide)
      p.push_back("omni.radius_outer: must be at most " + std::to_string(2 * limits::kMaxImageSide));
  }
  finite(o.azimuth_zero_deg, "omni.azimuth_zero_deg");
  if (finite(c.sensor.readout_s, "sensor.readout_s") &&
      !(std::abs(c.sensor.readout_s) <= SensorTiming::kMaxReadoutS))
    p.push_back("sensor.readout_s: " + std::to_string(c.sensor.readout_s) +
                " s is longer than a frame can be read out (|readout_s| <= " +
                std::to_string(SensorTiming::kMaxReadoutS) + " s; 0 = global shutter)");
  if (finite(c.sensor.exposure_s, "sensor.exposure_s") &&
      !(c.sensor.exposure_s >= 0.0 && c.sensor.exposure_s <= SensorTiming::kMaxExposureS))
    p.push_back("sensor.exposure_s: " + std::to_string(c.sensor.exposure_s) +
                " s must be in [0, " + std::to_string(SensorTiming::kMaxExposureS) +
                "] (0 = not known)");
  if (c.imu) {
    const ImuCalibration& imu = *c.imu;
    if (!imu.rotation.coeffs().allFinite())
      p.push_back("imu.rotation: every component must be a finite number");
    else if (!(std::abs(imu.rotation.norm() - 1.0) <= ImuCalibration::kUnitTolerance))
      p.push_back("imu.rotation: [w, x, y, z] must be a unit quaternion (norm " +
                  std::to_string(imu.rotation.norm()) + ")");
    if (finite(imu.time_offset_s, "imu.time_offset_s") &&
        !(std::abs(imu.time_offset_s) <= ImuCalibration::kMaxTimeOffsetS))
      p.push_back("imu.time_offset_s: " + std::to_string(imu.time_offset_s) +
                  " s is not within +-" + std::to_string(ImuCalibration::kMaxTimeOffsetS) +
                  " s of the camera's clock");
    if (imu.gyro_noise_density && finite(*imu.gyro_noise_density, "imu.gyro_noise_density") &&
        !(*imu.gyro_noise_density > 0.0))
      p.push_back("imu.gyro_noise_density: must be > 0 rad/s/sqrt(Hz)");
  }
  const auto& q = c.panorama;
  size(q.width, limits::kMaxPanoramaWidth, "panorama.width");
  size(q.height, limits::kMaxPanoramaHeight, "panorama.height");
  if (finite(q.horizon_row, "panorama.horizon_row") &&
      !(q.horizon_row >= -0.5 && q.horizon_row <= q.height - 0.5))
    p.push_back("panorama.horizon_row: " + std::to_string(q.horizon_row) +
                " is outside the panorama rows [-0.5, " + std::to_string(q.height - 0.5) + "]");
  if (finite(q.forward_column, "panorama.forward_column") &&
      !(q.forward_column >= 0 && q.forward_column < q.width))
    p.push_back("panorama.forward_column: must be in [0, width)");

}

/// The lens model: loaded, of the image's size; the mask: of the image's size.
void checkLensModel(const Calibration& c, std::vector<std::string>& p) {
  const auto& o = c.omni;
  switch (o.model) {
    case LensModelKind::kLinear: break;
    case LensModelKind::kOcamCalib:
      if (!o.ocamcalib) {
        p.push_back("omni.ocamcalib_file: no OCamCalib model loaded");
      } else if (o.ocamcalib->width != o.image_width || o.ocamcalib->height != o.image_height) {
        p.push_back("omni.image_width/image_height: " + std::to_string(o.image_width) + "x" +
                    std::to_string(o.image_height) + " disagree with " + o.ocamcalib->origin + " (" +
                    std::to_string(o.ocamcalib->width) + "x" + std::to_string(o.ocamcalib->height) +
                    " with its crops)");
      }
      break;
    case LensModelKind::kMei:
      if (!o.mei) p.push_back("omni: model mei needs xi, K and D (or omnidir_file)");
      else
        for (const auto& m : o.mei->validate()) p.push_back("omni." + m);
      break;
  }
  if (!o.mask.empty() && (o.mask.type() != CV_8UC1 || o.mask.cols != o.image_width ||
                          o.mask.rows != o.image_height)) {
    p.push_back("omni.mask: " + o.mask_file + " is " + std::to_string(o.mask.cols) + "x" +
                std::to_string(o.mask.rows) + " with " + std::to_string(o.mask.channels()) +
                " channel(s), expected 8-bit grey " + std::to_string(o.image_width) + "x" +
                std::to_string(o.image_height));
  }
}

/// A model's elevation must be monotonic over the used ring (else two rows of the panorama
/// would sample the same radius). False (with the problem added) when it is not.
bool checkMonotonicOverRing(const Calibration& c, std::vector<std::string>& p) {
  const auto& o = c.omni;
  const auto elevationAt = [&](double r) -> std::optional<double> {
    if (o.model == LensModelKind::kOcamCalib) return o.ocamcalib->elevation(r);
    const auto d = o.mei->direction({o.mei->cx + r, o.mei->cy});
    return d ? std::optional<double>(d->elevation) : std::nullopt;
  };
  const std::string source = o.model == LensModelKind::kOcamCalib
                                 ? "omni.ocamcalib_file: " + o.ocamcalib->origin + ": line " +
                                       std::to_string(o.ocamcalib->ss_line) + ": the direct polynomial"
                                 : std::string("omni: the mei model");
  std::optional<double> previous;
  int direction = 0;
  for (double r = o.radius_inner; r <= o.radius_outer + 1e-9; r += 0.25) {
    const auto e = elevationAt(r);
    if (!e) {
      p.push_back(source + " has no bearing at radius " + fixed(r) + " px inside the ring");
      return false;
    }
    if (previous) {
      const int d = *e > *previous ? 1 : (*e < *previous ? -1 : 0);
      if (d == 0 || (direction != 0 && d != direction)) {
        p.push_back(source + " is not monotonic over the ring [" + fixed(o.radius_inner) + ", " +
                    fixed(o.radius_outer) + "] px: its elevation turns at radius " + fixed(r) +
                    " px (" + fixed(deg(*e), 2) + " deg)");
        return false;
      }
      direction = d;
    }
    previous = e;
  }
  return true;
}

/// Every panorama row must lie inside the ring's elevations.
void checkRowsInsideRing(const Calibration& c, std::vector<std::string>& p) {
  const auto& o = c.omni;
  const auto& q = c.panorama;
  const auto [e_in, e_out] = c.ringElevations();
  const double lo = std::min(e_in, e_out), hi = std::max(e_in, e_out);
  const auto rowElevation = [&](double v) { return std::atan(q.cylinderHeight(v)); };
  int first_out = -1, last_out = -1;
  for (int v = 0; v < q.height; ++v) {
    if (rowElevation(v - 0.5) > hi || rowElevation(v + 0.5) < lo) {
      if (first_out < 0) first_out = v;
      last_out = v;
    }
  }
  if (first_out >= 0) {
    p.push_back("panorama: rows " + std::to_string(first_out) + ".." + std::to_string(last_out) +
                " (elevations " + fixed(deg(rowElevation(first_out)), 2) + ".." +
                fixed(deg(rowElevation(last_out)), 2) + " deg) lie outside the lens ring (elevations " +
                fixed(deg(lo), 2) + ".." + fixed(deg(hi), 2) + " deg between radius_inner " +
                fixed(o.radius_inner) + " and radius_outer " + fixed(o.radius_outer) +
                " px); lower panorama.height, move horizon_row or widen the ring");
  }
}

}  // namespace

std::vector<std::string> Calibration::validate() const {
  std::vector<std::string> p;
  checkFields(*this, p);
  checkLensModel(*this, p);
  if (!p.empty() || omni.model == LensModelKind::kLinear) return p;
  if (checkMonotonicOverRing(*this, p)) checkRowsInsideRing(*this, p);
  return p;
}

// ---------------------------------------------------------------------------------------
// YAML
// ---------------------------------------------------------------------------------------

namespace {

/// Reads calibration.yaml's omni section into a Calibration, every problem into the reader,
/// in the order the keys are checked: the model, its own keys (the OCamCalib file, the mei
/// model, the linear lens's centre and edge), the image size and ring, then the azimuth
/// and the mask.
class OmniSection {
 public:
  OmniSection(YamlReader& r, YAML::Node omni, const std::filesystem::path& base_dir, Calibration& c)
      : r_(r), omni_(std::move(omni)), base_dir_(base_dir), c_(c) {}

  void read() {
    readModel();
    if (c_.omni.model == LensModelKind::kOcamCalib) {
      readOcamCalib();
    } else {
      notWith("ocamcalib_file", "it is the ocamcalib model's file");
      r_.get(omni_, "omni", "image_width", c_.omni.image_width, Need::kRequired);
      r_.get(omni_, "omni", "image_height", c_.omni.image_height, Need::kRequired);
      r_.get(omni_, "omni", "radius_inner", c_.omni.radius_inner, Need::kRequired);
      r_.get(omni_, "omni", "radius_outer", c_.omni.radius_outer, Need::kRequired);
    }
    if (c_.omni.model == LensModelKind::kMei) {
      readMei();
    } else {
      for (const char* key : {"omnidir_file", "xi", "K", "D"}) notWith(key, "it belongs to the mei model");
    }
    if (c_.omni.model == LensModelKind::kLinear) readLinear();
    readAzimuth();
    readMask();
  }

 private:
  std::filesystem::path resolve(const std::string& file) const {
    const std::filesystem::path p(file);
    return p.is_absolute() || base_dir_.empty() ? p : base_dir_ / p;
  }

  /// A lens model file's own problems, each under the key that names the file.
  void fileProblems(const std::string& key, const std::exception& e) {
    const auto* listed = dynamic_cast<const ConfigError*>(&e);
    if (!listed || listed->problems().empty()) {
      r_.problem(key, e.what());
      return;
    }
    for (const auto& p : listed->problems()) r_.problem(key, p);
  }

  void notWith(const char* key, const char* why) {
    if (omni_ && omni_[key])
      r_.problem(std::string("omni.") + key, std::string("not used with model ") + model_ + ": " + why);
  }

  void readModel() {
    r_.getNamed(omni_, "omni", "model", kLensModels, c_.omni.model, Need::kOptional, &model_);
  }

  /// The OCamCalib file gives the image size, the centre and (with its ROI line) the ring.
  void readOcamCalib() {
    notWith("center", "the centre comes from ocamcalib_file");
    notWith("outer_edge", "the polynomial gives every radius its elevation");
    if (r_.get(omni_, "omni", "ocamcalib_file", c_.omni.ocamcalib_file, Need::kRequired)) {
      try {
        c_.omni.ocamcalib = OcamCalibModel::load(resolve(c_.omni.ocamcalib_file));
        const OcamCalibModel& m = *c_.omni.ocamcalib;
        c_.omni.image_width = m.width;
        c_.omni.image_height = m.height;
        c_.omni.center_x = m.yc;
        c_.omni.center_y = m.xc;
        if (m.roi_min_radius) c_.omni.radius_inner = *m.roi_min_radius;
        if (m.roi_max_radius) c_.omni.radius_outer = *m.roi_max_radius;
      } catch (const std::exception& e) {
        fileProblems("omni.ocamcalib_file", e);
      }
    }
    int w = c_.omni.image_width, h = c_.omni.image_height;
    if (r_.get(omni_, "omni", "image_width", w, Need::kOptional) && c_.omni.ocamcalib &&
        w != c_.omni.image_width)
      r_.problem("omni.image_width", std::to_string(w) + " disagrees with the OCamCalib file (" +
                                         std::to_string(c_.omni.image_width) + " with its crops)");
    if (r_.get(omni_, "omni", "image_height", h, Need::kOptional) && c_.omni.ocamcalib &&
        h != c_.omni.image_height)
      r_.problem("omni.image_height", std::to_string(h) + " disagrees with the OCamCalib file (" +
                                          std::to_string(c_.omni.image_height) + ")");
    const bool has_roi = c_.omni.ocamcalib && c_.omni.ocamcalib->roi_max_radius;
    const Need need_radii = !has_roi && c_.omni.ocamcalib ? Need::kRequired : Need::kOptional;
    r_.get(omni_, "omni", "radius_inner", c_.omni.radius_inner, need_radii);
    r_.get(omni_, "omni", "radius_outer", c_.omni.radius_outer, need_radii);
  }

  /// The mei model from omnidir_file or from xi, K and D; its principal point is the centre.
  void readMei() {
    notWith("center", "the centre is K's principal point");
    notWith("outer_edge", "the model gives every radius its elevation");
    const bool inline_model = omni_ && (omni_["xi"] || omni_["K"] || omni_["D"]);
    if (r_.get(omni_, "omni", "omnidir_file", c_.omni.omnidir_file, Need::kOptional)) {
      if (inline_model) r_.problem("omni.omnidir_file", "give either omnidir_file or xi, K and D, not both");
      try {
        c_.omni.mei = MeiModel::loadFileStorage(resolve(c_.omni.omnidir_file));
      } catch (const std::exception& e) {
        fileProblems("omni.omnidir_file", e);
      }
    } else {
      MeiModel m;
      std::vector<double> K, D;
      const bool ok_xi = r_.get(omni_, "omni", "xi", m.xi, Need::kRequired);
      const bool ok_k = r_.getNumbers(omni_, "omni", "K", 9, K);
      const bool ok_d = r_.getNumbers(omni_, "omni", "D", 4, D);
      if (ok_xi && ok_k && ok_d) {
        m.fx = K[0], m.s = K[1], m.cx = K[2], m.fy = K[4], m.cy = K[5];
        m.k1 = D[0], m.k2 = D[1], m.p1 = D[2], m.p2 = D[3];
        c_.omni.mei = m;
      }
    }
    if (c_.omni.mei) {
      c_.omni.center_x = c_.omni.mei->cx;
      c_.omni.center_y = c_.omni.mei->cy;
    }
  }

  /// The linear lens: its centre [x, y] and which panorama edge the outer ring becomes.
  void readLinear() {
    if (omni_) {
      const YAML::Node center = omni_["center"];
      if (!center) {
        r_.problem("omni.center", "missing");
      } else if (!center.IsSequence() || center.size() != 2) {
        r_.problem("omni.center", "must be a list [x, y]");
      } else {
        try {
          c_.omni.center_x = center[0].as<double>();
          c_.omni.center_y = center[1].as<double>();
        } catch (const YAML::Exception&) {
          r_.problem("omni.center", "must hold two numbers");
        }
      }
    }
    r_.getNamed(omni_, "omni", "outer_edge", kOuterEdges, c_.omni.outer_edge);
  }

  void readAzimuth() {
    r_.get(omni_, "omni", "azimuth_zero_deg", c_.omni.azimuth_zero_deg, Need::kOptional);
    r_.getNamed(omni_, "omni", "azimuth_direction", kAzimuthDirections,
                c_.omni.azimuth_direction);
  }

  void readMask() {
    if (!r_.get(omni_, "omni", "mask", c_.omni.mask_file, Need::kOptional)) return;
    const std::filesystem::path file = resolve(c_.omni.mask_file);
    const Expected<cv::Mat> mask = readImage(file, ImageColour::kAsStored);
    if (!mask) {
      // The decoder's message starts with the path: keep only its reason.
      std::string why(mask.error().message());
      if (why.starts_with(file.string() + ": ")) why.erase(0, file.string().size() + 2);
      r_.problem("omni.mask", file.string() + ": cannot read the mask image (" + why + ")");
    } else if (mask->type() != CV_8UC1) {
      r_.problem("omni.mask", file.string() + ": must be an 8-bit grey image (0 = never use)");
    } else {
      c_.omni.mask = *mask;
    }
  }

  YamlReader& r_;
  const YAML::Node omni_;
  const std::filesystem::path& base_dir_;
  Calibration& c_;
  std::string model_ = "linear";
};

/// Section `imu`: rotation [w, x, y, z] (required, normalised), time_offset_s and
/// gyro_noise_density (optional).
void readImuSection(YamlReader& r, const YAML::Node& node, Calibration& c) {
  if (!r.checkMap(node, "imu", {"rotation", "time_offset_s", "gyro_noise_density"})) return;
  ImuCalibration imu;
  if (std::vector<double> q; r.getNumbers(node, "imu", "rotation", 4, q))
    imu.rotation = Eigen::Quaterniond(q[0], q[1], q[2], q[3]);
  r.get(node, "imu", "time_offset_s", imu.time_offset_s, Need::kOptional);
  if (double density = 0.0; r.get(node, "imu", "gyro_noise_density", density, Need::kOptional))
    imu.gyro_noise_density = density;
  c.imu = imu;
}

}  // namespace

Calibration Calibration::parse(const std::string& text, const std::string& origin,
                               const std::filesystem::path& base_dir) {
  YamlReader r(origin);
  const YAML::Node root = detail::loadYaml(text, origin);
  r.checkDuplicateKeys(root);
  Calibration c;
  if (!root || !root.IsMap()) {
    r.problem("(document)", "expected a map with sections 'omni' and 'panorama'");
  } else {
    r.checkMap(root, "", {"omni", "panorama", "sensor", "imu"}, "unknown section");
    const auto section = [&](const std::string& name, const std::vector<std::string>& known) {
      const YAML::Node node = YamlReader::child(root, name);
      if (!node) {
        r.problem(name, "missing section");
        return YAML::Node(YAML::NodeType::Undefined);
      }
      return r.checkMap(node, name, known) ? node : YAML::Node(YAML::NodeType::Undefined);
    };
    const YAML::Node omni = section(
        "omni", {"model", "image_width", "image_height", "center", "radius_inner", "radius_outer",
                 "azimuth_zero_deg", "azimuth_direction", "outer_edge", "ocamcalib_file",
                 "omnidir_file", "xi", "K", "D", "mask"});
    OmniSection(r, omni, base_dir, c).read();

    const YAML::Node pano = section("panorama", {"width", "height", "horizon_row", "forward_column"});
    r.get(pano, "panorama", "width", c.panorama.width, Need::kRequired);
    r.get(pano, "panorama", "height", c.panorama.height, Need::kRequired);
    c.panorama.horizon_row = 0.5 * c.panorama.height - 0.5;  // default: the middle
    r.get(pano, "panorama", "horizon_row", c.panorama.horizon_row, Need::kOptional);
    r.get(pano, "panorama", "forward_column", c.panorama.forward_column, Need::kOptional);

    if (const YAML::Node sensor = YamlReader::child(root, "sensor");
        sensor && r.checkMap(sensor, "sensor", {"readout_s", "exposure_s", "timestamp"})) {
      r.get(sensor, "sensor", "readout_s", c.sensor.readout_s, Need::kOptional);
      r.get(sensor, "sensor", "exposure_s", c.sensor.exposure_s, Need::kOptional);
      r.getNamed(sensor, "sensor", "timestamp", kStampedAt, c.sensor.stamped_at, Need::kOptional);
    }
    if (const YAML::Node imu = YamlReader::child(root, "imu"); imu) readImuSection(r, imu, c);
  }
  // Range checks only make sense on values that were read.
  if (r.problems().empty()) {
    for (const auto& p : c.validate()) r.add(p);
  }
  if (r.problems().empty() && c.imu) c.imu->rotation.normalize();
  r.throwIfProblems("invalid calibration");
  return c;
}

Calibration Calibration::load(const std::filesystem::path& path) {
  Expected<std::string> text = readTextFile(path);
  if (!text) throw ConfigError(std::string(text.error().message()) + " (the calibration file)");
  return parse(*text, path.string(), path.parent_path());
}

std::string Calibration::toYaml() const {
  std::ostringstream o;
  o.precision(12);
  o << "omni:\n";
  if (omni.model != LensModelKind::kLinear) o << "  model: " << toString(omni.model) << "\n";
  if (omni.model == LensModelKind::kOcamCalib)
    o << "  ocamcalib_file: " << std::filesystem::path(omni.ocamcalib_file).filename().string() << "\n";
  o << "  image_width: " << omni.image_width << "\n"
    << "  image_height: " << omni.image_height << "\n";
  if (omni.model == LensModelKind::kLinear)
    o << "  center: [" << omni.center_x << ", " << omni.center_y << "]\n";
  if (omni.model == LensModelKind::kMei && omni.mei) {
    const MeiModel& m = *omni.mei;
    o << "  xi: " << m.xi << "\n"
      << "  K: [" << m.fx << ", " << m.s << ", " << m.cx << ", 0, " << m.fy << ", " << m.cy
      << ", 0, 0, 1]\n"
      << "  D: [" << m.k1 << ", " << m.k2 << ", " << m.p1 << ", " << m.p2 << "]\n";
  }
  o << "  radius_inner: " << omni.radius_inner << "\n"
    << "  radius_outer: " << omni.radius_outer << "\n"
    << "  azimuth_zero_deg: " << omni.azimuth_zero_deg << "\n"
    << "  azimuth_direction: " << toString(omni.azimuth_direction)
    << "\n";
  if (omni.model == LensModelKind::kLinear)
    o << "  outer_edge: " << toString(omni.outer_edge) << "\n";
  if (!omni.mask.empty())
    o << "  mask: " << std::filesystem::path(omni.mask_file.empty() ? "mask.png" : omni.mask_file).filename().string()
      << "\n";
  o << "panorama:\n"
    << "  width: " << panorama.width << "\n"
    << "  height: " << panorama.height << "\n"
    << "  horizon_row: " << panorama.horizon_row << "\n"
    << "  forward_column: " << panorama.forward_column << "\n";
  const bool stamp_stated = sensor.stamped_at != StampedAt::kExposureMiddle;
  if (sensor.readout_s != 0.0 || sensor.exposure_s != 0.0 || stamp_stated) {
    o << "sensor:\n";
    if (sensor.readout_s != 0.0) o << "  readout_s: " << sensor.readout_s << "\n";
    if (sensor.exposure_s != 0.0) o << "  exposure_s: " << sensor.exposure_s << "\n";
    if (stamp_stated) o << "  timestamp: " << toString(sensor.stamped_at) << "\n";
  }
  if (imu) {
    const Eigen::Quaterniond& q = imu->rotation;
    o.precision(17);
    o << "imu:\n  rotation: [" << q.w() << ", " << q.x() << ", " << q.y() << ", " << q.z()
      << "]  # camera from IMU, [w, x, y, z]\n"
      << "  time_offset_s: " << imu->time_offset_s << "\n";
    if (imu->gyro_noise_density) o << "  gyro_noise_density: " << *imu->gyro_noise_density << "\n";
  }
  return o.str();
}

void Calibration::save(const std::filesystem::path& path) const {
  const std::filesystem::path dir = path.parent_path();
  const auto beside = [&](const std::string& file, const char* fallback) {
    return dir / std::filesystem::path(file.empty() ? fallback : file).filename();
  };
  if (omni.model == LensModelKind::kOcamCalib && omni.ocamcalib) {
    const auto file = beside(omni.ocamcalib_file, "calib_results.txt");
    std::ofstream out(file);
    out << omni.ocamcalib->text;
    if (!out) throw std::runtime_error(file.string() + ": cannot write the OCamCalib file");
  }
  if (!omni.mask.empty()) {
    const auto file = beside(omni.mask_file, "mask.png");
    bool ok = false;
    try {
      ok = cv::imwrite(file.string(), omni.mask);
    } catch (const cv::Exception&) {
      ok = false;
    }
    if (!ok) throw std::runtime_error(file.string() + ": cannot write the mask");
  }
  std::ofstream out(path);
  if (!out) throw std::runtime_error(path.string() + ": cannot write calibration file");
  out << toYaml();
  if (!out) throw std::runtime_error(path.string() + ": write failed");
}

// ---------------------------------------------------------------------------------------
// Geometry
// ---------------------------------------------------------------------------------------

namespace {

double azimuthSign(const OmniLens& lens) {
  return lens.azimuth_direction == AzimuthDirection::kCw ? 1.0 : -1.0;
}
/// Image angle a of robot azimuth theta, and back.
double imageAngleOf(const OmniLens& lens, double theta) {
  return lens.azimuth_zero_deg * kDegToRad + azimuthSign(lens) * theta;
}
double azimuthOf(const OmniLens& lens, double image_angle) {
  return azimuthSign(lens) * (image_angle - lens.azimuth_zero_deg * kDegToRad);
}

/// Panorama row of omni radius r (linear model): the inverse of radiusOfRow.
double linearRowOfRadius(const Calibration& c, double r) {
  const double step = (c.omni.radius_outer - c.omni.radius_inner) / c.panorama.height;
  return c.omni.outer_edge == OuterEdge::kTop ? (c.omni.radius_outer - r) / step - 0.5
                                              : (r - c.omni.radius_inner) / step - 0.5;
}

}  // namespace

double rowTime(double y, int rows, double readout_s) {
  if (readout_s >= 0.0) return readout_s * y / rows;
  return -readout_s * (rows - 1 - y) / rows;
}

double Calibration::captureTime(double u, double v) const {
  if (sensor.readout_s == 0.0) return 0.0;
  const Eigen::Vector2d xy = omniPixel(u, v);
  if (!std::isfinite(xy.y())) return std::numeric_limits<double>::quiet_NaN();
  return rowTime(xy.y(), omni.image_height, sensor.readout_s);
}

double Calibration::radiusOfRow(double v) const {
  const double step = (omni.radius_outer - omni.radius_inner) / panorama.height;
  return omni.outer_edge == OuterEdge::kTop ? omni.radius_outer - (v + 0.5) * step
                                            : omni.radius_inner + (v + 0.5) * step;
}

Eigen::Vector2d Calibration::omniPixel(double u, double v) const {
  if (omni.model == LensModelKind::kLinear) {
    const double a = imageAngleOf(omni, panorama.azimuth(u));
    const double r = radiusOfRow(v);
    return {omni.center_x + r * std::cos(a), omni.center_y + r * std::sin(a)};
  }
  const auto p = pixelOfBearing(panorama.bearing(u, v));
  return p ? *p : Eigen::Vector2d(kNaN, kNaN);
}

Eigen::Vector2d Calibration::panoramaPixel(double x, double y) const {
  if (omni.model == LensModelKind::kLinear) {
    const double dx = x - omni.center_x, dy = y - omni.center_y;
    const double theta = azimuthOf(omni, std::atan2(dy, dx));
    return {panorama.column(theta), linearRowOfRadius(*this, std::hypot(dx, dy))};
  }
  const auto b = bearingOfPixel(x, y);
  return b ? panoramaOfBearing(panorama, *b) : Eigen::Vector2d(kNaN, kNaN);
}

std::optional<Eigen::Vector3d> Calibration::bearingOfPixel(double x, double y) const {
  switch (omni.model) {
    case LensModelKind::kLinear: {
      const Eigen::Vector2d uv = panoramaPixel(x, y);
      return panorama.bearing(uv.x(), uv.y());
    }
    case LensModelKind::kOcamCalib: {
      const LensDirection d = omni.ocamcalib->direction({x, y});
      return bearingOf(azimuthOf(omni, d.image_angle), d.elevation);
    }
    case LensModelKind::kMei: {
      const auto d = omni.mei->direction({x, y});
      if (!d) return std::nullopt;
      return bearingOf(azimuthOf(omni, d->image_angle), d->elevation);
    }
  }
  return std::nullopt;
}

std::optional<Eigen::Vector2d> Calibration::pixelOfBearing(const Eigen::Vector3d& b) const {
  const double horizontal = std::hypot(b.x(), b.y());
  if (!(horizontal > 0) || !b.allFinite()) return std::nullopt;
  const double theta = std::atan2(b.y(), b.x());
  switch (omni.model) {
    case LensModelKind::kLinear:
      return omniPixel(panorama.column(theta), panorama.row(b.z() / horizontal));
    case LensModelKind::kOcamCalib: {
      const auto rho = omni.ocamcalib->radius(std::atan2(b.z(), horizontal));
      if (!rho) return std::nullopt;
      return omni.ocamcalib->pixel(imageAngleOf(omni, theta), *rho);
    }
    case LensModelKind::kMei:
      return omni.mei->pixel(imageAngleOf(omni, theta), std::atan2(b.z(), horizontal));
  }
  return std::nullopt;
}

double Calibration::ringRadius(double x, double y) const {
  if (omni.model == LensModelKind::kOcamCalib) return omni.ocamcalib->direction({x, y}).radius;
  return std::hypot(x - omni.center_x, y - omni.center_y);
}

std::pair<double, double> Calibration::ringElevations() const {
  switch (omni.model) {
    case LensModelKind::kLinear: {
      const auto elevation = [&](double r) {
        return std::atan(panorama.cylinderHeight(linearRowOfRadius(*this, r)));
      };
      return {elevation(omni.radius_inner), elevation(omni.radius_outer)};
    }
    case LensModelKind::kOcamCalib:
      return {omni.ocamcalib->elevation(omni.radius_inner), omni.ocamcalib->elevation(omni.radius_outer)};
    case LensModelKind::kMei: {
      const auto elevation = [&](double r) {
        const auto d = omni.mei->direction({omni.mei->cx + r, omni.mei->cy});
        return d ? d->elevation : kNaN;
      };
      return {elevation(omni.radius_inner), elevation(omni.radius_outer)};
    }
  }
  return {kNaN, kNaN};
}

}  // namespace omnipose
