#pragma once
/// \file synth.hpp
/// The exact renderer: synthetic omni-image and panorama sequences with exact ground truth.
/// It is the referee for every sign and formula of the project (DESIGN.md sections 2, 3):
/// each output pixel looks exactly along the bearing that the calibration assigns to it.
///
/// World frame: x, y horizontal, z up (metres). The camera frame is x forward, y left,
/// z up; a pose T_world_camera maps camera coordinates to world coordinates. At the
/// identity pose the camera sits at the world origin, level, looking along world +x.
///
/// Equirectangular texture convention (a W_t x H_t photo, pixel centres at integers):
///   longitude lon = atan2(d_y, d_x)  counter-clockwise seen from above, lon = 0 is world +x
///   latitude  lat = asin(d_z)        +pi/2 straight up
///   column x = W_t * (0.5 - lon / (2 pi)) - 0.5,   row y = H_t * (0.5 - lat / pi) - 0.5
/// so world +x is the centre column, world +y (lon = 90 deg) a quarter of the width to the
/// left of it, and the top row is the zenith: an ordinary, non-mirrored 360-degree photo
/// seen from the inside. (The panorama of DESIGN.md runs the other way: theta grows with u,
/// so a panorama is the mirror image of the photo; both follow from the conventions.)
///
/// Camera and world effects, each exact against the definition its declaration states:
/// rolling shutter and exposure time (motion blur) in FrameTiming, people walking around
/// the robot in Walkers, track vibration in Vibration, vignetting in Vignetting, sensor
/// blur, noise, exposure jitter and auto-exposure steps in DegradeOptions.
///
/// Example: a 100-frame yaw sequence of omni images, written as a dataset
/// ```
///   auto scene = synth::Scene::load("indoor.jpg", synth::SceneKind::kSphere);
///   synth::Renderer renderer(scene, Calibration{}, {});
///   auto script = synth::MotionScript::preset("yaw");
///   auto poses = synth::generateTrajectory(script);
///   synth::DatasetWriter writer("out", Calibration{}, 0);
///   for (std::size_t k = 0; k < poses.size(); ++k)
///     writer.addFrame(synth::degrade(renderer.render(poses[k].pose), {}, k), poses[k]);
///   writer.finish();
/// ```

#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <opencv2/core.hpp>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/io/trajectory.hpp"

namespace omnipose::synth {

// ---------------------------------------------------------------------------------------
// Scene
// ---------------------------------------------------------------------------------------

/// What the equirectangular texture is painted on.
enum class SceneKind {
  kSphere,  ///< at infinity: only the camera's rotation matters, pure rotation is exact
  kBox,     ///< the walls, floor and ceiling of a box room: translation gives parallax
};

/// A box room, axis-aligned in the world frame, centred on the z axis. Metres.
/// Its surfaces are textured by projecting the equirect photo from the world origin (the
/// camera's identity position), so at the identity pose a box render equals a sphere render.
struct Box {
  double length = 6.0;    ///< extent along world x, walls at x = +-length/2
  double width = 5.0;     ///< extent along world y, walls at y = +-width/2
  double floor = -1.0;    ///< z of the floor (camera height above it: -floor)
  double ceiling = 1.5;   ///< z of the ceiling

  /// One message per bad field (empty = valid): length, width > 0, floor < 0 < ceiling
  /// (the origin must be inside the room).
  std::vector<std::string> validate() const;
  /// The region a camera may move in: the room shrunk by `wall_margin` from the four walls
  /// and by `floor_ceiling_margin` from floor and ceiling (an interval shrunk past its
  /// middle collapses to the middle). Metres.
  Eigen::AlignedBox3d interior(double wall_margin, double floor_ceiling_margin = 0.5) const;
  /// Whether world point p lies inside the room.
  bool contains(const Eigen::Vector3d& p) const;
};

// ---------------------------------------------------------------------------------------
// Walkers (people moving around the robot)
// ---------------------------------------------------------------------------------------

/// People walking around the robot: independently moving occluders in the world. Each
/// person is a vertical textured cylinder (solid: side and both caps) of diameter width_m,
/// from z = base to z = base + height_m, whose axis walks a horizontal circle about the world
/// z axis at constant speed:
///   axis(t) = distance * (cos a(t), sin a(t)),
///   a(t) = azimuth0 + direction * speed * t / distance,
/// t in seconds on the sequence's clock (a frame's timestamp plus its rows' capture times),
/// azimuth counter-clockwise from world +x. A ray sees the first surface point of the nearest
/// walker it meets before the scene (a sphere is at infinity; box walls are farther than any
/// valid walker). A camera inside a walker sees that walker's inside surface: walkers do not
/// avoid the camera.
///
/// Per person i (0-based) a generator seeded by (seed, i) alone draws, in this order: the
/// distance uniform in [min_distance_m, max_distance_m], azimuth0 uniform in [0, 2 pi), the
/// direction +1 (counter-clockwise) or -1 with probability 1/2, then its texture (see Walker:
/// 3..6 bands of grey 30..225 with stripes of 2..8 cycles and amplitude 0..40, then 2..5
/// blotches of amplitude +-25..70).
/// So person i is the same whatever `count` is.
struct Walkers {
  int count = 0;                    ///< people, [0, 100]; 0 = none
  double width_m = 0.5;             ///< cylinder diameter, metres, (0, 2]
  double height_m = 1.7;            ///< cylinder height, metres, > 0
  /// z of the feet, metres; none = the floor (Scene::box.floor, also for a sphere scene:
  /// by default the camera 1 m above the ground).
  std::optional<double> base_z = std::nullopt;
  double speed_m_s = 1.2;           ///< walking speed along the circle, m/s, [0, 20]
  double min_distance_m = 1.5;      ///< circle radius range, metres: width_m / 2 < min <= max
  double max_distance_m = 2.0;
  std::uint64_t seed = 0;

  /// One message per bad field (empty = valid), each starting with "walkers.<field>".
  std::vector<std::string> validate() const;
  /// validate(), and for a box scene that every walker stays inside the room at all times:
  /// max_distance_m + width_m / 2 at most half the smaller of the room's length and width,
  /// the feet at or above the floor and the top at or below the ceiling.
  std::vector<std::string> validate(SceneKind kind, const Box& box) const;
};

/// One drawn person of Walkers (see there for the motion).
struct Walker {
  double distance_m = 0.0;    ///< radius of the axis' circle about the world z axis
  double azimuth0_rad = 0.0;  ///< azimuth of the axis at t = 0
  double rate_rad_s = 0.0;    ///< da/dt = +-speed / distance
  double radius_m = 0.0;      ///< width / 2
  double base_z = 0.0, top_z = 0.0;

  /// Texture, grey levels: a function of the angle `a` around the axis measured from the
  /// direction away from the world origin (so the pattern turns with the person as it
  /// walks around) and of the height fraction f = (z - base) / (top - base) in [0, 1]:
  /// horizontal bands of clothing, band j for band_edge[j] <= f < band_edge[j + 1]
  /// (band_edge starts at 0 and ends at 1), each of grey band_grey[j] plus vertical stripes
  /// amplitude * sin(cycles * a + phase_rad) (whole cycles around the body), plus Gaussian
  /// blotches amplitude * exp(-(da / sigma_rad)^2 / 2 - (df / sigma_fraction)^2 / 2); the
  /// sum clamped to [16, 240].
  std::vector<double> band_edge;
  std::vector<double> band_grey;
  struct Stripes {
    double amplitude, cycles, phase_rad;
  };
  std::vector<Stripes> band_stripes;  ///< one per band
  struct Blotch {
    double angle_rad, height_fraction, sigma_rad, sigma_fraction, amplitude;
  };
  std::vector<Blotch> blotches;

  /// Azimuth a(t) of the axis, radians (not wrapped).
  double azimuth(double t) const { return azimuth0_rad + rate_rad_s * t; }
  /// Axis position (x, y) at time t, metres.
  Eigen::Vector2d position(double t) const;
  /// Grey level at `angle_rad` around the axis (see band_edge) and height fraction f.
  double grey(double angle_rad, double height_fraction) const;
  /// Ray parameter s > 0 of the first point of the walker's surface on origin + s * direction
  /// at time t (for a ray starting inside the walker: where it leaves it); none if missed.
  std::optional<double> hit(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction,
                            double t) const;
};

/// Draws the people of `walkers` (see Walkers), feet at walkers.base_z or else at `floor_z`.
/// Throws std::invalid_argument listing the problems of walkers.validate().
std::vector<Walker> drawWalkers(const Walkers& walkers, double floor_z);

/// "COUNT[,WIDTH_M,HEIGHT_M,SPEED_M_S]" over `base` (the fields not given keep base's
/// values); throws std::invalid_argument naming the text or the bad field otherwise.
Walkers parseWalkers(const std::string& text, const Walkers& base = {});

/// An equirectangular texture on a sphere at infinity or on a box room, and the people
/// walking in it.
struct Scene {
  cv::Mat texture;  ///< equirect, CV_32FC1, grey levels 0..255 (2:1 aspect expected)
  SceneKind kind = SceneKind::kSphere;
  Box box;          ///< used when kind == kBox (and its floor for the walkers' feet)
  Walkers walkers;  ///< none by default

  /// Loads a photo (any format OpenCV reads, converted to grey). Throws
  /// std::runtime_error naming the file when it cannot be read, or an invalid box.
  static Scene load(const std::filesystem::path& photo, SceneKind kind, const Box& box = {});
  /// Direction from the texture's projection centre (world origin) to the surface point
  /// seen from world point `origin` along world direction `direction` (not normalised).
  /// Sphere: `direction` itself. Box: the point where the ray leaves the room.
  Eigen::Vector3d textureDirection(const Eigen::Vector3d& origin,
                                   const Eigen::Vector3d& direction) const;
};

/// An equirectangular texture made from a real omni image: what a camera under a mirror saw,
/// as a photo the renderer can paint on a sphere or a room.
struct EquirectFromOmni {
  cv::Mat texture;        ///< CV_8UC1, width x width / 2, the convention above
  cv::Mat seen;           ///< CV_8UC1, same size: 255 where the ring saw the bearing, else 0
  double elevation_min = 0.0;  ///< lowest and highest elevation of the ring, radians
                               ///< (Calibration::ringElevations)
  double elevation_max = 0.0;
  double fill = 0.0;      ///< grey level of every unseen texel: the mean of the seen ones
};

/// Resamples `omni` (8-bit grey or BGR, the frame size of `calibration`) into an
/// equirectangular texture of `width` x width/2 texels: texel (x, y) looks along the
/// bearing of the convention above, taken as a camera-frame bearing at the identity pose,
/// and gets the omni image bilinearly at calibration.pixelOfBearing of it, where its
/// elevation is one the ring sees, that pixel lies at least one pixel inside the used ring
/// (radius_inner + 1 .. radius_outer - 1, so no sample reaches beyond it) and, with a mask,
/// on a used pixel.
/// Every other texel (above or below the ring's elevations) gets the seen texels' mean, a
/// flat surface. Rendering the texture through `calibration` at the identity pose gives
/// back the ring's image (to the bilinear resampling). Throws std::invalid_argument when
/// the image size differs from the calibration's, `width` is not an even number in
/// [16, 16384], or the ring sees no texel.
EquirectFromOmni equirectFromOmni(const cv::Mat& omni, const Calibration& calibration, int width);

/// "sphere" | "box"; throws std::invalid_argument naming the value otherwise.
SceneKind parseSceneKind(const std::string& name);
const char* toString(SceneKind kind);

// ---------------------------------------------------------------------------------------
// Renderer
// ---------------------------------------------------------------------------------------

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
  /// Builds the texture pyramid and draws the walkers. Throws std::invalid_argument listing
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
  /// parabola through it and its two neighbours (at the first and last sample the one
  /// step's). Passes through every sample; a constant velocity and, for a translation or a
  /// rotation about a fixed axis, a motion quadratic in time (a constant acceleration) are
  /// reproduced exactly.
  kSmooth,
};

/// poseAtTime() with the given motion between samples; kConstantVelocity is poseAtTime().
/// Before the first sample or after the last, kSmooth continues with the end sample's
/// velocity.
Eigen::Isometry3d poseAtTime(std::span<const StampedPose> trajectory, double t,
                             Interpolation interpolation);

// ---------------------------------------------------------------------------------------
// Static occluder (what the robot sees of itself)
// ---------------------------------------------------------------------------------------

/// A mast, body or cable bundle in a fixed sector of the ring: the same textured pattern in
/// every frame, so it stays still while the scene moves (and, unmasked, pulls every window
/// it covers towards zero motion). Omni output only.
struct Occluder {
  double image_angle_deg = 0.0;  ///< centre of the sector, image angle atan2(y - cy, x - cx)
  double width_deg = 40.0;       ///< angular width of the sector, degrees, in (0, 360)

  /// One message per bad field (empty = valid).
  std::vector<std::string> validate() const;
  /// Paints the occluder over a rendered omni image (CV_32FC1, grey 0..255) within the
  /// calibration's ring [radius_inner - 2, radius_outer + 2] px.
  void paint(cv::Mat& image, const Calibration& calibration) const;
  /// The mask that hides it: CV_8UC1 of the frame size, 0 inside the sector widened by
  /// `margin_deg` on each side, 255 elsewhere.
  cv::Mat mask(const Calibration& calibration, double margin_deg = 2.0) const;
};

/// "ANGLE,WIDTH" in degrees; throws std::invalid_argument naming the text otherwise.
Occluder parseOccluder(const std::string& text);

// ---------------------------------------------------------------------------------------
// Vignetting
// ---------------------------------------------------------------------------------------

/// Brightness falloff of the lens away from its optical centre. Omni pixel (x, y) is
/// multiplied by
///   V(x, y) = max(0, 1 - strength * (r / radius_outer)^2),   r = calibration.ringRadius(x, y)
/// (r is the distance from the mirror axis (center_x, center_y) in pixels for the linear
/// lens, the model's ideal radius otherwise), so V = 1 - strength at the ring's outer edge
/// for every lens model and V = 0 where the parabola would go negative (the corners).
/// Panorama pixel (u, v) is multiplied by V at the omni pixel it is unwrapped from,
/// calibration.omniPixel(u, v) (1 where that is undefined): the factor an unwrapped
/// vignetted omni image shows (for the linear lens a function of the row alone).
struct Vignetting {
  double strength = 0.0;  ///< in [0, 1]; 0 = none

  /// One message per bad field (empty = valid).
  std::vector<std::string> validate() const;
  /// V of omni pixel (x, y) (pixel coordinates, x right, y down).
  double factor(const Calibration& calibration, double x, double y) const;
  /// The factor image of an output: CV_32FC1 of the omni image or the panorama size.
  cv::Mat factors(const Calibration& calibration, OutputKind output) const;
  /// Multiplies a rendered image (CV_32FC1 of `output`'s size) by factors(). Throws
  /// std::invalid_argument on an invalid strength or an image of another type or size.
  void apply(cv::Mat& image, const Calibration& calibration, OutputKind output) const;
};

// ---------------------------------------------------------------------------------------
// Degradations
// ---------------------------------------------------------------------------------------

/// Sensor effects applied to a rendered float image, in this order: Gaussian blur (optics),
/// exposure (gain, offset), Gaussian noise, rounding to 8 bit. JPEG compression is applied
/// when the frame is written (DatasetWriter). All random draws are seeded by (seed, frame),
/// so a frame's degradation does not depend on which other frames were rendered.
///
/// Exposure: I' = g_k I + o with g_k = A_k * (1 + N(0, exposure_gain_std)), A_k the
/// auto-exposure gain of frame k (exposureStepGain) and o ~ N(0, exposure_offset_std).
///
/// Auto-exposure steps: the gain a controller sets steps now and then by a whole factor:
///   A_k = (1 + exposure_step)^n_k,
/// n_0 = 0; n_k = n_{k-1} except at the step frames k = m * exposure_step_every (m >= 1),
/// where a sign s_k = +1 or -1 (probability 1/2, drawn from a generator seeded by (seed, k)
/// alone, apart from the frame's other draws) gives n_k = n_{k-1} + s_k, or n_{k-1} - s_k
/// when |n_{k-1} + s_k| would exceed exposure_step_levels (the controller's range). So
/// exposure_step = 0.25 makes each step x1.25 or /1.25, and A_k depends on (seed, k) only.
struct DegradeOptions {
  double noise_sigma = 0.0;          ///< sensor noise std, grey levels
  double blur_sigma = 0.0;           ///< Gaussian blur std, pixels (0 = off)
  double exposure_gain_std = 0.0;    ///< per-frame gain 1 + N(0, std) (e.g. 0.05)
  double exposure_offset_std = 0.0;  ///< per-frame offset N(0, std), grey levels
  std::uint64_t seed = 0;
  bool periodic_columns = false;     ///< blur wraps around columns (panorama output)
  double exposure_step = 0.0;        ///< auto-exposure step, relative, [0, 1] (0 = none)
  int exposure_step_every = 0;       ///< frames between steps, >= 0 (0 = none)
  int exposure_step_levels = 2;      ///< most steps away from the start gain, [1, 16]

  /// One message per bad field (empty = valid): every std >= 0, the steps' ranges above.
  std::vector<std::string> validate() const;
};

/// A_k, the auto-exposure gain of frame `frame` (see DegradeOptions): 1 without steps.
/// Costs frame / exposure_step_every draws. Throws std::invalid_argument on invalid options.
double exposureStepGain(const DegradeOptions& options, std::uint64_t frame);

/// Applies the degradations to a CV_32FC1 image (grey 0..255) for frame number `frame`;
/// returns CV_8UC1 (values rounded and clamped to 0..255). Deterministic for the same
/// options and frame. Throws std::invalid_argument on invalid options or a non-float image.
cv::Mat degrade(const cv::Mat& image, const DegradeOptions& options, std::uint64_t frame);

// ---------------------------------------------------------------------------------------
// Motion scripts
// ---------------------------------------------------------------------------------------

/// Per-frame rotation increment omega (the relative rotation R = exp([omega]x) of DESIGN.md
/// section 2, in the previous camera's frame).
struct RotationStep {
  /// x = roll, y = pitch, z = yaw (camera axes); random = direction uniform on the sphere.
  enum class Axis { kX, kY, kZ, kRandom };
  enum class Sign { kRandom, kAlternate, kPositive, kNegative };
  Axis axis = Axis::kZ;
  double min_deg = 1.0;  ///< |omega| drawn uniformly in [min_deg, max_deg], degrees
  double max_deg = 6.0;
  Sign sign = Sign::kRandom;  ///< sign of omega along a fixed axis (ignored for kRandom)
  /// If > 0: when a step would turn the camera more than bound_deg away from the start
  /// orientation (angle of the accumulated rotation), the opposite step is taken instead
  /// if that stays closer; keeps roll/pitch sequences bounded. Degrees.
  double bound_deg = 0.0;
};

/// Per-frame translation increment t (DESIGN.md section 2: the current camera's position in
/// the previous camera's frame).
struct TranslationStep {
  double min_m = 0.05;  ///< |t| drawn uniformly in [min_m, max_m], metres
  double max_m = 0.15;
  /// true: a uniformly random horizontal direction in the world frame; a step that would
  /// leave the allowed region is redrawn. false: `direction` in the camera frame; at the
  /// region's boundary the motion bounces (reverses for the rest of the segment).
  bool random_horizontal = true;
  Eigen::Vector3d direction = Eigen::Vector3d::UnitX();
};

/// Track vibration: a roll and pitch perturbation of the camera's attitude on top of the
/// scripted trajectory, as a tracked robot's chassis shakes on the ground. It does not
/// accumulate: frame k's pose is T_k = S_k * [R_vib(t_k) | 0], with S_k the scripted pose,
/// t_k = k / frame_rate and R_vib(t) = exp([roll(t), pitch(t), 0]x) (a rotation about the
/// camera centre; the position is the scripted one).
///
/// Each of roll and pitch is a sum of `components` sinusoids,
///   angle(t) = scale * sum_i w_i sin(2 pi f_i t + phi_i),
/// with weights w_i uniform in [0.5, 1], phases phi_i uniform in [0, 2 pi) and frequencies
/// f_i = m_i / D drawn without repetition from the whole numbers m_i of cycles over the
/// sequence's duration D = (frames - 1) / frame_rate whose frequency lies in
/// [min_hz, max_hz]. The vibration is therefore periodic over the sequence: it ends with the
/// attitude it began with, and its mean over frames 0 .. frames - 2 (one period) is zero.
/// `scale` makes the largest |angle(t_k)| over the sequence's frames exactly amplitude_deg.
/// Roll and pitch are drawn independently (roll first) from a generator seeded by `seed`
/// alone, so the scripted trajectory does not depend on the vibration.
struct Vibration {
  double amplitude_deg = 0.5;  ///< peak |roll| and peak |pitch| over the frames, degrees
  double min_hz = 1.0;         ///< lowest frequency, Hz
  double max_hz = 9.0;         ///< highest frequency, Hz (below half the frame rate)
  int components = 3;          ///< sinusoids per axis
  std::uint64_t seed = 0;

  /// One message per bad field (empty = valid), each starting with "vibration.<field>":
  /// amplitude_deg in (0, 10], 0 < min_hz <= max_hz, components in [1, 16].
  std::vector<std::string> validate() const;
};

/// One axis of a drawn vibration: angle(t) = scale_rad * sum_i weight[i] *
/// sin(2 pi frequency_hz[i] t + phase_rad[i]), radians.
struct VibrationAxis {
  std::vector<double> frequency_hz, phase_rad, weight;
  double scale_rad = 0.0;
  /// The angle at time t (seconds), radians.
  double angle(double t) const;
};

/// The vibration a script draws for its frames (see Vibration).
struct VibrationSignal {
  VibrationAxis roll, pitch;
  /// R_vib(t) = exp([roll.angle(t), pitch.angle(t), 0]x); t in seconds.
  Eigen::Matrix3d rotation(double t) const;
};

/// Draws the vibration of a sequence of `frames` frames at `frame_rate` Hz. Throws
/// std::invalid_argument naming the field when `vibration` is invalid, when frames < 2,
/// when max_hz is not below frame_rate / 2, or when the band holds fewer whole-cycle
/// frequencies over the sequence than `components`.
VibrationSignal drawVibration(const Vibration& vibration, int frames, double frame_rate);

/// `frames` consecutive increments, each with an optional rotation and translation.
struct MotionSegment {
  int frames = 1;
  std::optional<RotationStep> rotation;
  std::optional<TranslationStep> translation;
};

/// Thrown by MotionScript::load/parse: the configuration error, each problem naming the
/// file and the field (e.g. "m.yaml: segments[1].rotation.axis: 'w' is not x, y, z or random").
using MotionError = ConfigError;

/// A motion script. YAML format (every key but `segments` optional; defaults shown):
/// ```yaml
/// seed: 0                # random draws (steps, signs, directions)
/// frame_rate: 30.0       # Hz: frame i has timestamp i / frame_rate seconds
/// frames: 0              # total frames including the first; 0 = 1 + sum of segment frames,
///                        #   else the segments are cycled (or cut) to give exactly this many
/// wall_margin_m: 1.0     # box scene: the camera stays this far from the walls
/// vibration:             # optional track vibration (struct Vibration), on top of the segments
///   amplitude_deg: 0.5   #   peak |roll| and |pitch|, degrees
///   min_hz: 1            #   frequency band, Hz
///   max_hz: 9
///   components: 3        #   sinusoids per axis
///   seed: 0              #   its own random draws
/// walkers:               # optional people walking around the robot (struct Walkers)
///   count: 3             #   people, 0..100
///   width_m: 0.5         #   diameter, metres
///   height_m: 1.7        #   metres
///   base_z: -1.0         #   z of the feet, metres (default: the box room's floor)
///   speed_m_s: 1.2       #   walking speed along their circles, m/s
///   distance_m: [1.5, 2.0]   # circle radius about the world z axis, metres (or one number)
///   seed: 0              #   their own random draws
/// segments:
///   - frames: 50                 # increments in this segment
///     rotation:                  # optional
///       axis: z                  # x (roll) | y (pitch) | z (yaw) | random
///       step_deg: [1, 6]         # per-frame angle range, degrees (or one number)
///       sign: random             # random | alternate | positive | negative (fixed axes)
///       bound_deg: 0             # 0 = unbounded
///     translation:               # optional
///       step_m: [0.05, 0.15]     # per-frame distance range, metres (or one number)
///       direction: random_horizontal   # or [x, y, z] in the camera frame
/// ```
/// The scripted poses: S_0 = identity, S_k = S_{k-1} * [exp(omega_k), t_k]. Without
/// vibration T_k = S_k; with it T_k = S_k * [R_vib(t_k) | 0] (so T_0 = R_vib(0)).
struct MotionScript {
  std::uint64_t seed = 0;
  double frame_rate = 30.0;  ///< Hz
  int frames = 0;            ///< total frame count, 0 = 1 + sum of segment frames
  double wall_margin_m = 1.0;
  std::vector<MotionSegment> segments;
  std::optional<Vibration> vibration;  ///< track vibration, none by default
  /// People walking around (for Scene::walkers; the trajectory does not use them), none by
  /// default. validate() checks their fields; whether they fit a box room is checked where
  /// the scene is known (Walkers::validate(kind, box)).
  std::optional<Walkers> walkers;

  /// One message per bad field (empty = valid).
  std::vector<std::string> validate() const;
  /// Number of frames generateTrajectory() produces.
  int frameCount() const;
  /// The vibration generateTrajectory() applies (drawVibration() for frameCount() frames),
  /// or none. Throws std::invalid_argument like drawVibration().
  std::optional<VibrationSignal> vibrationSignal() const;
  /// Whether any segment translates (needs a box scene to be visible).
  bool translates() const;

  /// Reads a YAML motion script; throws MotionError listing every problem with the path.
  /// `frames`: replaces the script's `frames` before it is validated (what depends on the
  /// frame count, the vibration's band, is judged for that count).
  static MotionScript load(const std::filesystem::path& path, std::optional<int> frames = {});
  /// Parses YAML text; `origin` names the source in error messages; `frames` as in load().
  static MotionScript parse(const std::string& yaml_text, const std::string& origin = "<string>",
                            std::optional<int> frames = {});
  /// The paper's protocol: "roll", "pitch", "yaw" (100 frames, 1..6 deg per frame about
  /// one axis, random sign, roll/pitch bounded to 15 deg), "mixed" (100 frames, up to 12 deg
  /// per frame about a random axis, bounded to 20 deg), "translate" (100 frames, 5..15 cm
  /// horizontal steps in random directions plus up to 1 deg of rotation, box scene),
  /// "demo" (60 frames: yaw, roll, pitch, then translation). Throws MotionError naming
  /// the preset when unknown.
  static MotionScript preset(const std::string& name);
  /// The YAML text of a preset (what preset() parses).
  static std::string presetYaml(const std::string& name);
  /// Names of all presets.
  static std::vector<std::string> presetNames();
};

/// The camera poses T_world_camera of a script (the scripted poses times the vibration, if
/// any; see MotionScript), timestamps i / frame_rate. `region`: where the camera may be
/// (world frame); translation steps respect it (see TranslationStep). Throws MotionError if
/// no step keeps the camera inside the region, std::invalid_argument on an invalid script.
std::vector<StampedPose> generateTrajectory(const MotionScript& script,
                                            const std::optional<Eigen::AlignedBox3d>& region = {});

// ---------------------------------------------------------------------------------------
// Dataset writer
// ---------------------------------------------------------------------------------------

/// Writes a dataset directory (DESIGN.md section 6):
/// ```
///   DIR/calibration.yaml   DIR/frames/000000.png (or .jpg)   DIR/timestamps.txt
///   DIR/groundtruth.tum    (camera poses relative to the first frame, so it is the identity)
/// ```
class DatasetWriter {
 public:
  /// Creates DIR and DIR/frames and writes calibration.yaml. `jpeg_quality` 1..100 writes
  /// JPEG frames of that quality, 0 lossless PNG. Throws std::runtime_error naming the path
  /// when a directory cannot be created or written, or when DIR/frames is not empty
  /// (stale frames of an older run would be replayed).
  DatasetWriter(std::filesystem::path directory, const Calibration& calibration,
                int jpeg_quality = 0);

  /// Writes the next frame (CV_8UC1) with its timestamp and ground-truth pose
  /// T_world_camera. Throws std::runtime_error naming the file when it cannot be written.
  void addFrame(const cv::Mat& image, const StampedPose& pose);
  /// Writes timestamps.txt and groundtruth.tum. Throws std::runtime_error naming the file.
  void finish();

  /// File name (no directory) of frame number i, e.g. "000007.png".
  std::string frameName(std::size_t i) const;
  const std::filesystem::path& directory() const { return directory_; }

 private:
  std::filesystem::path directory_;
  int jpeg_quality_;
  std::vector<StampedPose> poses_;
};

}  // namespace omnipose::synth
