#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>
#include <span>
#include <stdexcept>
#include <string>

#include "omnipose/so3.hpp"
#include "omnipose/synth/renderer.hpp"
#include "synth/equirect.hpp"
#include "synth/walker_hit.hpp"

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

std::vector<std::string> FrameTiming::validate() const {
  std::vector<std::string> p;
  if (!std::isfinite(timestamp_s)) p.push_back("timestamp_s: must be finite");
  if (!std::isfinite(readout_s)) p.push_back("readout_s: must be finite");
  if (!(exposure_s >= 0 && std::isfinite(exposure_s))) {
    p.push_back("exposure_s: must be a finite number >= 0 seconds");
  }
  if (exposure_samples < 0 || exposure_samples > kMaxExposureSamples) {
    p.push_back("exposure_samples: must be in [0, " + std::to_string(kMaxExposureSamples) +
                "] (0 = chosen from the motion)");
  }
  return p;
}

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
  for (const auto& p : scene_.walkers.validate(scene_.kind, scene_.box)) {
    problems.push_back("scene." + p);
  }
  if (!problems.empty()) throw std::invalid_argument("Renderer:" + joinLines(problems));
  pyramid_ = detail::buildPyramid(scene_.texture);
  walkers_ = drawWalkers(scene_.walkers, scene_.box.floor);
  ray_table_ = buildRayTable();
}

cv::Size Renderer::outputSize() const {
  if (options_.output == OutputKind::kPanorama) {
    return calibration_.panorama.size();
  }
  return {calibration_.omni.image_width, calibration_.omni.image_height};
}

void Renderer::checkInsideRoom(const Eigen::Isometry3d& T, int row) const {
  if (scene_.kind != SceneKind::kBox || scene_.box.contains(T.translation())) return;
  throw std::invalid_argument(
      "Renderer::render: the camera is outside the box room" +
      (row < 0 ? std::string() : " at row " + std::to_string(row)));
}

cv::Mat Renderer::render(const Eigen::Isometry3d& T_world_camera) const {
  return render(T_world_camera, 0.0);
}

cv::Mat Renderer::render(const Eigen::Isometry3d& T_world_camera, double time_s) const {
  checkInsideRoom(T_world_camera, -1);
  cv::Mat out(outputSize(), CV_32FC1);
  const std::vector<View> views(static_cast<std::size_t>(out.rows), View{T_world_camera, time_s});
  cv::parallel_for_(cv::Range(0, out.rows), [&](const cv::Range& rows) {
    renderRows(views, 1, rows.start, rows.end, out);
  });
  return out;
}

cv::Mat Renderer::render(const std::function<Eigen::Isometry3d(double)>& pose_at,
                         double readout_s) const {
  return render(pose_at, FrameTiming{.readout_s = readout_s});
}

cv::Mat Renderer::render(const std::function<Eigen::Isometry3d(double)>& pose_at,
                         const FrameTiming& timing) const {
  if (const auto problems = timing.validate(); !problems.empty()) {
    throw std::invalid_argument("Renderer::render: invalid timing:" + joinLines(problems));
  }
  const int n = exposureSamples(pose_at, timing);
  cv::Mat out(outputSize(), CV_32FC1);
  // Row y, sub-exposure i: pose_at(rowTime(y) + o_i), walkers at (timestamp + o_i) +
  // rowTime(y): exactly what render(t -> pose_at(t + o_i), {timestamp + o_i, readout}) uses.
  std::vector<View> views(static_cast<std::size_t>(out.rows) * static_cast<std::size_t>(n));
  for (int y = 0; y < out.rows; ++y) {
    const double t = rowTime(y, out.rows, timing.readout_s);
    for (int i = 0; i < n; ++i) {
      const double o = n == 1 ? 0.0 : timing.exposure_s * ((i + 0.5) / n - 0.5);
      View& view = views[static_cast<std::size_t>(y) * n + i];
      view.pose = pose_at(n == 1 ? t : t + o);
      view.time_s = (timing.timestamp_s + o) + t;
      checkInsideRoom(view.pose, y);
    }
  }
  cv::parallel_for_(cv::Range(0, out.rows), [&](const cv::Range& rows) {
    renderRows(views, n, rows.start, rows.end, out);
  });
  return out;
}

double Renderer::pixelsPerRadian() const {
  if (options_.output == OutputKind::kPanorama) return 1.0 / calibration_.panorama.gamma();
  const OmniLens& lens = calibration_.omni;
  const auto [inner, outer] = calibration_.ringElevations();
  const double radial = (lens.radius_outer - lens.radius_inner) / std::abs(outer - inner);
  return std::max(lens.radius_outer, std::isfinite(radial) ? radial : 0.0);
}

int Renderer::exposureSamples(const std::function<Eigen::Isometry3d(double)>& pose_at,
                              const FrameTiming& timing) const {
  if (const auto problems = timing.validate(); !problems.empty()) {
    throw std::invalid_argument("Renderer::exposureSamples: invalid timing:" + joinLines(problems));
  }
  if (timing.exposure_s == 0.0) return 1;
  if (timing.exposure_samples > 0) return timing.exposure_samples;
  constexpr int kSteps = 8;               // 9 sampled times per row's exposure
  constexpr double kNearestWalker = 0.05;  // metres
  const int rows = outputSize().height;
  const Eigen::AlignedBox3d room(
      Eigen::Vector3d(-0.5 * scene_.box.length, -0.5 * scene_.box.width, scene_.box.floor),
      Eigen::Vector3d(0.5 * scene_.box.length, 0.5 * scene_.box.width, scene_.box.ceiling));
  double motion_rad = 0.0;
  for (const int y : {0, rows / 2, rows - 1}) {
    const double centre = rowTime(y, rows, timing.readout_s);
    double turn = 0.0, path = 0.0, walker_rate = 0.0;
    double nearest = std::numeric_limits<double>::infinity();
    Eigen::Isometry3d previous = Eigen::Isometry3d::Identity();
    for (int s = 0; s <= kSteps; ++s) {
      const double t = centre + timing.exposure_s * (static_cast<double>(s) / kSteps - 0.5);
      const Eigen::Isometry3d T = pose_at(t);
      const Eigen::Vector3d p = T.translation();
      if (s > 0) {
        turn += rotationVector(previous.linear().transpose() * T.linear()).norm();
        path += (p - previous.translation()).norm();
      }
      previous = T;
      if (scene_.kind == SceneKind::kBox) {
        const Eigen::Vector3d below = p - room.min(), above = room.max() - p;
        nearest = std::min({nearest, below.minCoeff(), above.minCoeff()});
      }
      for (const Walker& w : walkers_) {
        const double gap = (p.head<2>() - w.position(timing.timestamp_s + t)).norm() - w.radius_m;
        const double speed = std::abs(w.rate_rad_s) * w.distance_m;
        walker_rate = std::max(walker_rate, speed / std::max(kNearestWalker, gap));
      }
    }
    const double parallax = scene_.kind == SceneKind::kBox && path > 0.0
                                ? path / std::max(nearest, 1e-3)
                                : 0.0;
    motion_rad = std::max(motion_rad, turn + parallax + timing.exposure_s * walker_rate);
  }
  const double n = std::ceil(pixelsPerRadian() * motion_rad / 0.5);
  if (!(n >= 1.0)) return 1;  // no motion (or NaN)
  return static_cast<int>(std::min(n, static_cast<double>(kMaxAutoExposureSamples)));
}

Eigen::Isometry3d poseBetween(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double s) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = a.linear() * rotationFromVector(s * rotationVector(a.linear().transpose() * b.linear()));
  T.translation() = a.translation() + s * (b.translation() - a.translation());
  return T;
}

namespace {

/// The step [k, k + 1] of a trajectory (at least two samples) containing t: the first or last
/// step for a t outside the samples.
std::size_t stepAt(std::span<const StampedPose> trajectory, double t) {
  std::size_t k = 0;
  while (k + 2 < trajectory.size() && trajectory[k + 1].timestamp <= t) ++k;
  return k;
}

}  // namespace

Eigen::Isometry3d poseAtTime(std::span<const StampedPose> trajectory, double t) {
  if (trajectory.empty()) throw std::invalid_argument("poseAtTime: empty trajectory");
  if (trajectory.size() == 1) return trajectory.front().pose;
  const std::size_t k = stepAt(trajectory, t);
  const StampedPose& a = trajectory[k];
  const StampedPose& b = trajectory[k + 1];
  return poseBetween(a.pose, b.pose, (t - a.timestamp) / (b.timestamp - a.timestamp));
}

namespace {

using Vec6 = Eigen::Matrix<double, 6, 1>;

/// The smooth motion at time t: on the step [a, b] around t, the tangent-space coordinates
/// x (rotation vector of a^-1 R(t), position) and their time derivative (see
/// Interpolation::kSmooth). Requires at least two samples.
struct SmoothState {
  const StampedPose* a = nullptr;
  Vec6 x, rate;
};

SmoothState smoothStateAt(std::span<const StampedPose> trajectory, double t) {
  const std::size_t n = trajectory.size();
  const std::size_t k = stepAt(trajectory, t);
  const StampedPose& a = trajectory[k];
  const StampedPose& b = trajectory[k + 1];
  const double h = b.timestamp - a.timestamp;
  // Sample j in the tangent space at sample c: (rotation vector of c^-1 j, position).
  const auto local = [&](std::size_t c, std::size_t j) {
    Vec6 x;
    x << rotationVector(trajectory[c].pose.linear().transpose() * trajectory[j].pose.linear()),
        trajectory[j].pose.translation();
    return x;
  };
  const Vec6 p0 = local(k, k), p1 = local(k, k + 1);
  const Vec6 secant = (p1 - p0) / h;
  // The velocity at inner sample j, in its own tangent space (so its rotation part is the
  // body rate there, whichever step it is seen from): the derivative of the parabola through
  // it and its neighbours (exact for a motion quadratic in time, whatever the spacing).
  const auto velocity = [&](std::size_t j) {
    const Vec6 before = local(j, j - 1), at = local(j, j), after = local(j, j + 1);
    const double hm = trajectory[j].timestamp - trajectory[j - 1].timestamp;
    const double hp = trajectory[j + 1].timestamp - trajectory[j].timestamp;
    return Vec6((hm * hm * (after - at) + hp * hp * (at - before)) / (hm * hp * (hm + hp)));
  };
  // At the trajectory's ends the step's own velocity. At b the body rate w is turned into
  // the rate of a's coordinates: rightJacobian(x) dx/dt = w.
  const Vec6 v0 = k > 0 ? velocity(k) : secant;
  Vec6 v1 = secant;
  if (k + 2 < n) {
    v1 = velocity(k + 1);
    v1.head<3>() = rightJacobian(p1.head<3>()).inverse() * Vec6(v1).head<3>();
  }
  SmoothState state{.a = &a, .x = Vec6::Zero(), .rate = Vec6::Zero()};
  if (t < a.timestamp) {  // before the first sample
    state.x = p0 + (t - a.timestamp) * v0;
    state.rate = v0;
  } else if (t > b.timestamp) {  // after the last
    state.x = p1 + (t - b.timestamp) * v1;
    state.rate = v1;
  } else {
    // Cubic Hermite basis on s in [0, 1] and its derivative (d/dt = d/ds / h).
    const double s = (t - a.timestamp) / h, s2 = s * s, s3 = s2 * s;
    state.x = (2 * s3 - 3 * s2 + 1) * p0 + (s3 - 2 * s2 + s) * h * v0 + (-2 * s3 + 3 * s2) * p1 +
              (s3 - s2) * h * v1;
    state.rate = ((6 * s2 - 6 * s) * p0 + (3 * s2 - 4 * s + 1) * h * v0 + (6 * s - 6 * s2) * p1 +
                  (3 * s2 - 2 * s) * h * v1) /
                 h;
  }
  return state;
}

/// The cumulative cubic B-spline of Interpolation::kSpline at time t: its pose and its body
/// rate. Requires at least two samples at uniform spacing.
struct SplineState {
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  Eigen::Vector3d rate = Eigen::Vector3d::Zero();
};

SplineState splineStateAt(std::span<const StampedPose> trajectory, double t) {
  const std::size_t n = trajectory.size();
  const double h = (trajectory.back().timestamp - trajectory.front().timestamp) / static_cast<double>(n - 1);
  for (std::size_t k = 1; k < n; ++k)
    if (std::abs(trajectory[k].timestamp - trajectory[k - 1].timestamp - h) > 1e-9 * (1.0 + h))
      throw std::invalid_argument("poseAtTime: a spline needs samples at uniform times (sample " +
                                  std::to_string(k) + " is not)");
  // Segment i spans [t_i, t_i+1] (the last segment continued beyond the ends), u its fraction.
  const double x = (t - trajectory.front().timestamp) / h;
  const auto i = static_cast<std::ptrdiff_t>(std::clamp(std::floor(x), 0.0, static_cast<double>(n - 2)));
  const double u = x - static_cast<double>(i);
  // Control pose j (j = -1 and n: the end step continued at constant velocity).
  const auto control = [&](std::ptrdiff_t j) -> Eigen::Isometry3d {
    if (j < 0) return poseBetween(trajectory[0].pose, trajectory[1].pose, static_cast<double>(j));
    if (j >= static_cast<std::ptrdiff_t>(n))
      return poseBetween(trajectory[n - 2].pose, trajectory[n - 1].pose, static_cast<double>(j - static_cast<std::ptrdiff_t>(n) + 2));
    return trajectory[static_cast<std::size_t>(j)].pose;
  };
  const std::array<Eigen::Isometry3d, 4> c = {control(i - 1), control(i), control(i + 1), control(i + 2)};
  // Cumulative basis functions of the uniform cubic B-spline and their derivatives (per u).
  const double u2 = u * u, u3 = u2 * u;
  const std::array<double, 3> b = {(5 + 3 * u - 3 * u2 + u3) / 6, (1 + 3 * u + 3 * u2 - 2 * u3) / 6, u3 / 6};
  const std::array<double, 3> db = {(3 - 6 * u + 3 * u2) / 6, (3 + 6 * u - 6 * u2) / 6, 3 * u2 / 6};
  SplineState state;
  Eigen::Matrix3d R = c[0].linear();
  Eigen::Vector3d p = c[0].translation();
  std::array<Eigen::Matrix3d, 3> A;
  std::array<Eigen::Vector3d, 3> omega;
  for (std::size_t j = 0; j < 3; ++j) {
    omega[j] = rotationVector(c[j].linear().transpose() * c[j + 1].linear());
    A[j] = rotationFromVector(b[j] * omega[j]);
    R = R * A[j];
    p += b[j] * (c[j + 1].translation() - c[j].translation());
  }
  state.pose.linear() = R;
  state.pose.translation() = p;
  // R = c0 A0 A1 A2, dA_j/dt = A_j [db_j omega_j / h]x: the body rate is each term carried
  // through the factors after it.
  state.rate = (A[2].transpose() * (A[1].transpose() * (db[0] * omega[0]) + db[1] * omega[1]) +
                db[2] * omega[2]) /
               h;
  return state;
}

}  // namespace

Eigen::Isometry3d poseAtTime(std::span<const StampedPose> trajectory, double t,
                             Interpolation interpolation) {
  if (interpolation == Interpolation::kConstantVelocity || trajectory.size() < 2)
    return poseAtTime(trajectory, t);
  if (interpolation == Interpolation::kSpline) return splineStateAt(trajectory, t).pose;
  const SmoothState state = smoothStateAt(trajectory, t);
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = state.a->pose.linear() * rotationFromVector(state.x.head<3>());
  T.translation() = state.x.tail<3>();
  return T;
}

Eigen::Vector3d angularVelocityAtTime(std::span<const StampedPose> trajectory, double t,
                                      Interpolation interpolation) {
  if (trajectory.empty()) throw std::invalid_argument("angularVelocityAtTime: empty trajectory");
  if (trajectory.size() == 1) return Eigen::Vector3d::Zero();
  if (interpolation == Interpolation::kSmooth) {
    const SmoothState state = smoothStateAt(trajectory, t);
    return rightJacobian(state.x.head<3>()) * state.rate.head<3>();
  }
  if (interpolation == Interpolation::kSpline) return splineStateAt(trajectory, t).rate;
  // Constant velocity: R(t) = R_a exp(s log(R_a^T R_b)), s = (t - t_a) / h, turns at
  // log(R_a^T R_b) / h about its own axes.
  const std::size_t k = stepAt(trajectory, t);
  const StampedPose& a = trajectory[k];
  const StampedPose& b = trajectory[k + 1];
  return rotationVector(a.pose.linear().transpose() * b.pose.linear()) /
         (b.timestamp - a.timestamp);
}

struct Renderer::PixelRays {
  /// One sub-sample: a bearing that sees the scene, or the lens body's grey level.
  struct Ray {
    Eigen::Vector3d bearing;
    float body = 0.0f;
    bool scene = false;
  };
  bool has_lod = false;                 ///< else mip level 0
  Eigen::Vector3d centre, right, below;  ///< bearings of the pixel and its neighbours (lod)
  std::vector<Ray> rays;                ///< k x k sub-samples, row by row
};

/// Every output pixel's PixelRays, row by row: the pixel's own fields in `pixels`, its k x k
/// sub-sample rays at rays[(y * width + x) * k * k ...]. Bearings in doubles, exactly as
/// omniRays() / panoramaRays() compute them, so a frame is the same bit for bit with or
/// without the table.
struct Renderer::RayTable {
  struct Pixel {
    Eigen::Vector3d centre, right, below;
    bool has_lod = false;
  };
  int width = 0;
  int samples = 0;  ///< k x k
  std::vector<Pixel> pixels;
  std::vector<PixelRays::Ray> rays;
};

namespace {

/// The largest ray table a renderer keeps (an 800 x 800 omni image with 1 x 1 rays takes
/// 72 MB, with 3 x 3 rays 230 MB); larger outputs compute their rays for every frame.
constexpr std::size_t kMaxRayTableBytes = std::size_t{256} << 20;

/// The box filter's sub-samples of pixel (x, y): sets rays.rays to k x k entries, row by row,
/// each given by set(sx, sy, ray) at its sub-pixel centre (x + (i + 0.5) / k - 0.5, ...).
template <typename Rays, typename Set>
void forSubPixels(int k, double x, double y, Rays& rays, const Set& set) {
  rays.rays.resize(static_cast<std::size_t>(k * k));
  for (int j = 0; j < k; ++j) {
    const double sy = y + (j + 0.5) / k - 0.5;
    for (int i = 0; i < k; ++i) {
      set(x + (i + 0.5) / k - 0.5, sy, rays.rays[static_cast<std::size_t>(j * k + i)]);
    }
  }
}

}  // namespace

std::shared_ptr<const Renderer::RayTable> Renderer::buildRayTable() const {
  const cv::Size size = outputSize();
  const auto pixels = static_cast<std::size_t>(size.area());
  const auto samples = static_cast<std::size_t>(options_.supersample) * options_.supersample;
  if (pixels * (sizeof(RayTable::Pixel) + samples * sizeof(PixelRays::Ray)) > kMaxRayTableBytes)
    return nullptr;
  auto table = std::make_shared<RayTable>();
  table->width = size.width;
  table->samples = static_cast<int>(samples);
  table->pixels.resize(pixels);
  table->rays.resize(pixels * samples);
  cv::parallel_for_(cv::Range(0, size.height), [&](const cv::Range& rows) {
    PixelRays rays;
    for (int y = rows.start; y < rows.end; ++y) {
      for (int x = 0; x < size.width; ++x) {
        computeRays(x, y, rays);
        const std::size_t i = static_cast<std::size_t>(y) * size.width + x;
        table->pixels[i] = {rays.centre, rays.right, rays.below, rays.has_lod};
        std::copy(rays.rays.begin(), rays.rays.end(), table->rays.begin() + i * samples);
      }
    }
  });
  return table;
}

void Renderer::computeRays(int x, int y, PixelRays& rays) const {
  if (options_.output == OutputKind::kOmni) omniRays(x, y, rays);
  else panoramaRays(x, y, rays);
}

void Renderer::pixelRays(int x, int y, PixelRays& rays) const {
  if (!ray_table_) {
    computeRays(x, y, rays);
    return;
  }
  const RayTable& table = *ray_table_;
  const std::size_t i = static_cast<std::size_t>(y) * table.width + x;
  const RayTable::Pixel& pixel = table.pixels[i];
  rays.has_lod = pixel.has_lod;
  rays.centre = pixel.centre;
  rays.right = pixel.right;
  rays.below = pixel.below;
  const auto first = table.rays.begin() + static_cast<std::ptrdiff_t>(i * table.samples);
  rays.rays.assign(first, first + table.samples);
}

void Renderer::renderRows(std::span<const View> views, int n, int row_begin, int row_end,
                          cv::Mat& out) const {
  PixelRays rays;
  std::vector<std::vector<PlacedWalker>> placed(static_cast<std::size_t>(n));
  for (int y = row_begin; y < row_end; ++y) {
    const View* row_views = views.data() + static_cast<std::size_t>(y) * n;
    // Every walker where it is at each sub-exposure's time of this row.
    for (int i = 0; i < n; ++i) {
      auto& at = placed[static_cast<std::size_t>(i)];
      at.clear();
      for (const Walker& w : walkers_) {
        at.push_back({&w, w.position(row_views[i].time_s), w.azimuth(row_views[i].time_s)});
      }
    }
    float* row = out.ptr<float>(y);
    for (int x = 0; x < out.cols; ++x) {
      pixelRays(x, y, rays);
      if (n == 1) {
        row[x] = shade(rays, row_views[0].pose, placed[0]);
        continue;
      }
      double sum = 0.0;
      for (int i = 0; i < n; ++i) {
        sum += shade(rays, row_views[i].pose, placed[static_cast<std::size_t>(i)]);
      }
      row[x] = static_cast<float>(sum / n);
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

void Renderer::panoramaRays(int u, int v, PixelRays& rays) const {
  const PanoramaGeometry& pano = calibration_.panorama;
  rays.has_lod = true;
  rays.centre = pano.bearing(u, v);
  rays.right = pano.bearing(u + 1, v);
  rays.below = pano.bearing(u, v + 1);
  forSubPixels(options_.supersample, u, v, rays, [&](double su, double sv, PixelRays::Ray& ray) {
    ray = {pano.bearing(su, sv), 0.0f, true};
  });
}

void Renderer::omniRays(int x, int y, PixelRays& rays) const {
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
  rays.has_lod = touches_ring;
  if (touches_ring) {
    rays.centre = bearingAt(x, y);
    rays.right = bearingAt(x + 1, y);
    rays.below = bearingAt(x, y + 1);
  }
  forSubPixels(options_.supersample, x, y, rays, [&](double sx, double sy, PixelRays::Ray& ray) {
    const auto b =
        touches_ring && inRing(sx, sy) ? calibration_.bearingOfPixel(sx, sy) : std::nullopt;
    ray.scene = b.has_value();
    if (b) ray.bearing = *b;
    else ray.body = lensBody(lens, calibration_.ringRadius(sx, sy));
  });
}

float Renderer::shade(const PixelRays& rays, const Eigen::Isometry3d& T,
                      std::span<const PlacedWalker> walkers) const {
  const double lod = rays.has_lod ? levelOfDetail(textureDirection(T, rays.centre),
                                                  textureDirection(T, rays.right),
                                                  textureDirection(T, rays.below))
                                  : 0.0;
  // Box filter: the mean of the sub-samples.
  double sum = 0.0;
  for (const PixelRays::Ray& ray : rays.rays) {
    sum += ray.scene ? sampleRay(T, ray.bearing, lod, walkers) : ray.body;
  }
  const int k = options_.supersample;
  return static_cast<float>(sum / (k * k));
}

float Renderer::sampleRay(const Eigen::Isometry3d& T, const Eigen::Vector3d& bearing, double lod,
                          std::span<const PlacedWalker> walkers) const {
  if (!walkers.empty()) {
    // The nearest walker on the ray, if any: it hides the scene (which lies beyond).
    const Eigen::Vector3d origin = T.translation(), direction = T.linear() * bearing;
    const PlacedWalker* nearest = nullptr;
    double nearest_s = std::numeric_limits<double>::infinity();
    for (const PlacedWalker& w : walkers) {
      const std::optional<double> s = detail::hitWalker(*w.walker, w.axis, origin, direction);
      if (s && *s < nearest_s) {
        nearest_s = *s;
        nearest = &w;
      }
    }
    if (nearest) {
      const Eigen::Vector3d p = origin + nearest_s * direction;
      const Walker& w = *nearest->walker;
      const double around = std::atan2(p.y() - nearest->axis.y(), p.x() - nearest->axis.x()) -
                            nearest->azimuth;
      return static_cast<float>(w.grey(around, (p.z() - w.base_z) / (w.top_z - w.base_z)));
    }
  }
  return detail::sampleEquirect(pyramid_, textureDirection(T, bearing), lod);
}

}  // namespace omnipose::synth
