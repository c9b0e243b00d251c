#pragma once
/// \file renderer.hpp
/// The exact renderer: each output pixel looks exactly along the bearing that the
/// calibration assigns to it; rolling shutter, exposure time and the walkers' motion are
/// rendered from their definitions. Also the trajectory interpolation it renders between
/// frame poses with.

#include <Eigen/Geometry>
#include <functional>
#include <memory>
#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/io/trajectory.hpp"
#include "omnipose/synth/scene.hpp"

namespace omnipose::synth {

/// What the renderer produces.
enum class OutputKind {
  kOmni,      ///< the donut image of the lens, calibration.omni.image_width x image_height
  kPanorama,  ///< the unwrapped panorama, calibration.panorama.width x height
};

/// "omni" | "panorama"; throws std::invalid_argument naming the value otherwise.
OutputKind parseOutputKind(const std::string& name);
const char* toString(OutputKind kind);

struct RenderOptions {
  OutputKind output = OutputKind::kOmni;
  /// Sub-pixel grid per axis: each output pixel is the box-filtered mean of
  /// supersample x supersample rays at the centres of a regular sub-grid.
  int supersample = 3;

  /// One message per bad field (empty = valid): supersample in [1, 16].
  std::vector<std::string> validate() const;
};

/// When and how one frame is exposed: its place on the sequence's clock, the rolling
/// shutter and the exposure time (motion blur). Times in seconds.
///
/// Row y of a frame of H rows (the omni image's sensor rows, or the panorama's rows when that
/// is the output) is captured at rowTime(y, H, readout_s) after the frame's timestamp and
/// exposed over the interval of length exposure_s centred on that capture time; its pixels
/// are the mean of the instantaneous image over that interval (a box shutter). It is
/// rendered as the mean of N sub-exposures at the midpoints of N equal sub-intervals: sub-
/// exposure i (0 <= i < N) is the instantaneous rolling-shutter render shifted in time by
///   o_i = exposure_s * ((i + 0.5) / N - 0.5),
/// i.e. row y seen from pose_at(rowTime(y) + o_i) with the walkers at
/// timestamp_s + rowTime(y) + o_i. exposure_s = 0 (or N = 1) is the instantaneous frame.
struct FrameTiming {
  double timestamp_s = 0.0;   ///< the frame's timestamp on the walkers' clock (Walkers)
  double readout_s = 0.0;     ///< rolling shutter readout (rowTime), 0 = global shutter
  double exposure_s = 0.0;    ///< exposure time, >= 0; 0 = no motion blur
  /// N; 0 = chosen from the motion (Renderer::exposureSamples). Ignored when exposure_s = 0.
  int exposure_samples = 0;

  /// One message per bad field (empty = valid): every time finite, exposure_s >= 0,
  /// exposure_samples in [0, kMaxExposureSamples].
  std::vector<std::string> validate() const;
};

/// Most sub-exposures FrameTiming::exposure_samples may ask for.
inline constexpr int kMaxExposureSamples = 256;
/// Most sub-exposures Renderer::exposureSamples chooses by itself.
inline constexpr int kMaxAutoExposureSamples = 64;

/// Renders the scene as seen by the calibrated camera at a given pose.
///
/// Panorama output: pixel (u, v) looks exactly along calibration.panorama.bearing(u, v).
/// Omni output: omni pixel (x, y) looks along bearing(calibration.panoramaPixel(x, y));
/// outside the used ring the lens body is drawn (a dark outer housing, a dark centre with a
/// faint grey reflection of the phone camera), so a circle detector finds the ring edges.
/// Anti-aliasing: supersampling (box filter over the pixel) over a mip pyramid of the
/// texture whose level follows the angular footprint of one sub-sample (trilinear lookup;
/// every level is centred on the texel grid of level 0, so filtering never shifts content).
/// Thread safety: render() is const and may be called from several threads.
class Renderer {
 public:
  /// Builds the texture pyramid, draws the walkers and computes every output pixel's rays
  /// (their bearings do not depend on the pose; kept when they take at most 256 MB: 112 bytes
  /// a pixel with 1 x 1 rays, 32 more per extra ray). Throws std::invalid_argument listing
  /// invalid options, calibration fields or walkers (Walkers::validate(kind, box)).
  Renderer(Scene scene, Calibration calibration, RenderOptions options = {});

  /// The image seen from camera pose T_world_camera: CV_32FC1, grey levels 0..255, of
  /// outputSize(). Box scene: throws std::invalid_argument if the camera is outside the
  /// room. Runs on all cores (cv::parallel_for_ over rows).
  cv::Mat render(const Eigen::Isometry3d& T_world_camera) const;

  /// Rolling shutter: as render(), but output row y (of the omni image: the sensor's rows;
  /// of the panorama when that is the output) is seen from pose_at(rowTime(y, H,
  /// readout_s)), H = outputSize().height: t is seconds after the frame's timestamp, the
  /// capture of the row read first. readout_s = 0 gives render(pose_at(0)). `pose_at` is
  /// called once per row, on the calling thread. Throws as render() for any row's pose.
  cv::Mat render(const std::function<Eigen::Isometry3d(double)>& pose_at, double readout_s) const;

  /// Global shutter at time `time_s` on the walkers' clock: render(T_world_camera) with the
  /// walkers (Scene::walkers) where they are at time_s. render(T) is render(T, 0).
  cv::Mat render(const Eigen::Isometry3d& T_world_camera, double time_s) const;

  /// Rolling shutter, exposure time and walkers (FrameTiming): the mean of N sub-exposures,
  /// N = exposureSamples(pose_at, timing), each row of each seen from
  /// pose_at(rowTime(y, H, readout_s) + o_i) (t relative to the timestamp, as above). Exactly
  /// render(pose_at, readout_s) for a timing of timestamp 0 without exposure time (or with
  /// N = 1); sub-exposure i is exactly render(t -> pose_at(t + o_i), {timestamp_s + o_i,
  /// readout_s}); the mean is taken in double and rounded to float once. `pose_at` is called
  /// N times per row (and a few times more when N is chosen), on the calling thread. Throws
  /// std::invalid_argument listing an invalid timing, or as render() for any row's pose.
  cv::Mat render(const std::function<Eigen::Isometry3d(double)>& pose_at,
                 const FrameTiming& timing) const;

  /// N, the sub-exposures render(pose_at, timing) averages: 1 when exposure_s = 0, else
  /// timing.exposure_samples when > 0, else enough that one sub-exposure moves the image by
  /// at most 0.5 px: N = clamp(ceil(m / 0.5), 1, kMaxAutoExposureSamples), m the image
  /// motion in pixels during one row's exposure, bounded from above (the largest over the
  /// first, middle and last row, each sampled at 9 times over its exposure interval) as
  ///   m = P * (sum of the rotation angles between consecutive sampled poses
  ///            + path length of the camera / distance to the nearest box plane (box scene)
  ///            + exposure_s * max over walkers and samples of speed / max(0.05 m, horizontal
  ///              distance from the camera to the walker's axis - its radius)),
  /// P the pixels per radian of the output: panorama 1 / gamma; omni the larger of
  /// radius_outer (an azimuth turn at the ring's outer edge) and the ring's mean radial scale
  /// (radius_outer - radius_inner) / |elevation(outer) - elevation(inner)|.
  int exposureSamples(const std::function<Eigen::Isometry3d(double)>& pose_at,
                      const FrameTiming& timing) const;

  /// Width x height of render()'s result, pixels.
  cv::Size outputSize() const;
  const Calibration& calibration() const { return calibration_; }
  const RenderOptions& options() const { return options_; }
  const Scene& scene() const { return scene_; }
  /// The people drawn from scene().walkers (empty without walkers).
  const std::vector<Walker>& walkers() const { return walkers_; }

 private:
  /// Where one row is seen from in one sub-exposure: the camera pose and the walkers' time.
  struct View {
    Eigen::Isometry3d pose;
    double time_s = 0.0;
  };
  /// A walker where it is at one view's time.
  struct PlacedWalker {
    const Walker* walker = nullptr;
    Eigen::Vector2d axis;  ///< axis position (x, y), metres
    double azimuth = 0.0;  ///< Walker::azimuth at that time, radians
  };
  /// The rays of one output pixel, which do not depend on the pose (renderer.cpp).
  struct PixelRays;
  /// Every output pixel's rays, computed once at construction when they fit in
  /// kMaxRayTableBytes (renderer.cpp); else each frame computes them again.
  struct RayTable;
  /// The rays of output pixel (x, y) as omniRays() or panoramaRays() compute them.
  void computeRays(int x, int y, PixelRays& rays) const;
  /// The rays of output pixel (x, y): from the table, or computed.
  void pixelRays(int x, int y, PixelRays& rays) const;
  /// The table of every pixel's rays, or null when it would be larger than
  /// kMaxRayTableBytes.
  std::shared_ptr<const RayTable> buildRayTable() const;

  /// Renders rows [row_begin, row_end), row y as the mean over its n views
  /// views[y * n + i], i < n (views.size() = rows * n).
  void renderRows(std::span<const View> views, int n, int row_begin, int row_end,
                  cv::Mat& out) const;
  void omniRays(int x, int y, PixelRays& rays) const;
  void panoramaRays(int u, int v, PixelRays& rays) const;
  /// The pixel's value seen from pose T with the walkers placed as given.
  float shade(const PixelRays& rays, const Eigen::Isometry3d& T_world_camera,
              std::span<const PlacedWalker> walkers) const;
  /// What one sub-sample ray (camera-frame bearing b) sees: the nearest walker or the scene.
  float sampleRay(const Eigen::Isometry3d& T_world_camera, const Eigen::Vector3d& bearing,
                  double lod, std::span<const PlacedWalker> walkers) const;
  /// Texture direction of camera-frame bearing b seen from pose T_world_camera.
  Eigen::Vector3d textureDirection(const Eigen::Isometry3d& T_world_camera,
                                   const Eigen::Vector3d& bearing) const;
  /// Pixels per radian of image motion (see exposureSamples).
  double pixelsPerRadian() const;
  void checkInsideRoom(const Eigen::Isometry3d& T_world_camera, int row) const;
  /// Mip level for one sub-sample of a pixel whose centre and right/lower neighbours have
  /// these texture directions.
  double levelOfDetail(const Eigen::Vector3d& centre, const Eigen::Vector3d& right,
                       const Eigen::Vector3d& below) const;

  Scene scene_;
  Calibration calibration_;
  RenderOptions options_;
  std::vector<cv::Mat> pyramid_;  ///< texture mip levels, level 0 = scene_.texture
  std::vector<Walker> walkers_;
  std::shared_ptr<const RayTable> ray_table_;  ///< null when it would not fit
};

/// Capture time of row y of a frame (calibration.hpp: the camera model's row timing, which
/// the renderer draws with).
using omnipose::rowTime;

/// The pose the fraction s of the way from `a` to `b`: rotation at constant angular velocity
/// (a.linear() * exp(s * log(a.linear()^T * b.linear()))), translation linear; s outside
/// [0, 1] extrapolates the same motion.
Eigen::Isometry3d poseBetween(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b, double s);

/// The pose at time t (seconds) of a trajectory sampled at increasing timestamps: poseBetween
/// the two samples around t, so the motion between frames is the constant-velocity step
/// from one to the next; before the first sample or after the last, the nearest step
/// extrapolated. A single sample is returned as it is. Requires a non-empty trajectory.
Eigen::Isometry3d poseAtTime(std::span<const StampedPose> trajectory, double t);

/// How a trajectory sampled at frame timestamps moves between its samples.
enum class Interpolation {
  /// Constant velocity from one sample to the next (poseBetween): the velocity jumps at
  /// every sample where the per-frame motion changes.
  kConstantVelocity,
  /// Velocity continuous through the samples (as a vehicle's, which cannot change speed
  /// in no time): on each step a cubic Hermite curve in the tangent space at its first
  /// sample (rotation vector and position) with, at each sample, the velocity of the
  /// parabola through it and its two neighbours in the tangent space at that sample (at
  /// the first and last sample the one step's), so the angular velocity
  /// (angularVelocityAtTime) is the same on either side of a sample; the acceleration is
  /// not (it changes at every sample). Passes through every sample; a constant velocity
  /// and, for a translation or a rotation about a fixed axis, a motion quadratic in time (a
  /// constant acceleration) are reproduced exactly.
  kSmooth,
  /// Velocity and acceleration continuous (as a vehicle's, whose forces cannot jump either):
  /// the cumulative cubic B-spline (Kim, Kim and Shin 1995; the rolling-shutter splines of
  /// Lovegrove et al. 2013) whose control poses are the samples, which must be uniformly
  /// spaced in time (std::invalid_argument otherwise): on [t_i, t_i+1], u = (t - t_i) / h,
  /// R(t) = R_{i-1} exp(b1(u) W1) exp(b2(u) W2) exp(b3(u) W3), W_j = log(R_{i+j-2}^T
  /// R_{i+j-1}), b1 = (5 + 3u - 3u^2 + u^3) / 6, b2 = (1 + 3u + 3u^2 - 2u^3) / 6, b3 = u^3 / 6,
  /// the position the same sums of differences; the end steps continue at constant velocity.
  /// It smooths: at t_i the pose is about 1/6, 4/6, 1/6 of samples i - 1, i, i + 1, so the
  /// frames' ground truth is the spline's own pose there. A constant velocity is
  /// reproduced exactly.
  kSpline,
};

/// poseAtTime() with the given motion between samples; kConstantVelocity is poseAtTime().
/// Before the first sample or after the last, kSmooth continues with the end sample's
/// velocity, kSpline with its end segment's cubic.
Eigen::Isometry3d poseAtTime(std::span<const StampedPose> trajectory, double t,
                             Interpolation interpolation);

/// The angular velocity at time t (seconds) of poseAtTime(trajectory, t, interpolation), rad/s
/// about the camera's own axes (x roll, y pitch, z yaw): w with R(t)^T dR/dt = [w]x, what a
/// gyro fixed to the camera measures. Exact (no finite differences); at a sample the step
/// that starts there (with kSmooth both steps agree). Zero for a single sample; throws
/// std::invalid_argument for an empty trajectory.
Eigen::Vector3d angularVelocityAtTime(std::span<const StampedPose> trajectory, double t,
                                      Interpolation interpolation);

}  // namespace omnipose::synth
