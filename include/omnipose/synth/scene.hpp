#pragma once
/// \file scene.hpp
/// What the exact renderer looks at: an equirectangular photo painted on a sphere at
/// infinity or on the walls of a box room, and the people walking around the robot.
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

#include <Eigen/Geometry>
#include <cstdint>
#include <filesystem>
#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

namespace omnipose::synth {

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

/// Another room from the same photo: the texture mirrored left to right when `mirrored`,
/// then turned about the vertical by `turn_deg` degrees (its columns rolled right by
/// turn_deg / 360 of its width, to the nearest column; any finite angle, taken modulo
/// 360). Throws std::invalid_argument for a non-finite angle or an empty texture.
void turnTexture(Scene& scene, double turn_deg, bool mirrored);

/// "sphere" | "box"; throws std::invalid_argument naming the value otherwise.
SceneKind parseSceneKind(const std::string& name);
const char* toString(SceneKind kind);

}  // namespace omnipose::synth
