// Tests of the renderer's camera and world effects (omnipose::synth): motion blur over the
// exposure time, people walking around the robot, auto-exposure steps and vignetting. Each
// is checked against the definition its header states.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>

#include "omnipose/so3.hpp"
#include "omnipose/synth/synth.hpp"
#include "point_unwrap.hpp"
#include "test_poses.hpp"

using ::testing::HasSubstr;

namespace omnipose::synth {
namespace {

constexpr double kPi = std::numbers::pi;
const std::filesystem::path kSourceDir = OMNIPOSE_SOURCE_DIR;
const std::filesystem::path kIndoor = kSourceDir / "tests/data/equirect/indoor_1024x512.jpg";
const Eigen::Isometry3d kIdentity = Eigen::Isometry3d::Identity();
using PoseAt = std::function<Eigen::Isometry3d(double)>;

using test::rotation;
using test::translation;

double maxAbsDiff(const cv::Mat& a, const cv::Mat& b) { return cv::norm(a, b, cv::NORM_INF); }

/// A scene whose texture is black everywhere: whatever is not black is a walker.
Scene blankScene(SceneKind kind) {
  Scene scene;
  scene.texture = cv::Mat(512, 1024, CV_32FC1, cv::Scalar(0));
  scene.kind = kind;
  return scene;
}

// ---------------------------------------------------------------------- motion blur

/// A yaw at a constant rate plus a little roll: the motion between two frames 1/30 s apart.
const std::vector<StampedPose> kTurn = {{0.0, kIdentity},
                                        {1.0 / 30.0, rotation({0.01, 0.0, 0.06})}};

PoseAt turning() {
  return [](double t) { return poseAtTime(kTurn, t); };
}

TEST(SynthMotionBlur, ZeroExposureIsTheInstantaneousFrameBitForBit) {
  const Renderer renderer(Scene::load(kIndoor, SceneKind::kSphere), Calibration{},
                          {OutputKind::kOmni, 1});
  const PoseAt pose_at = turning();
  const cv::Mat rolling = renderer.render(pose_at, 0.0267);
  EXPECT_EQ(renderer.exposureSamples(pose_at, {.readout_s = 0.0267}), 1);
  EXPECT_EQ(maxAbsDiff(renderer.render(pose_at, FrameTiming{.readout_s = 0.0267}), rolling), 0.0);
  // An explicit sample count does not matter without exposure time, nor does one sample.
  EXPECT_EQ(maxAbsDiff(renderer.render(pose_at, {.readout_s = 0.0267, .exposure_samples = 9}),
                       rolling),
            0.0);
  EXPECT_EQ(maxAbsDiff(renderer.render(pose_at, {.readout_s = 0.0267, .exposure_s = 0.01,
                                                 .exposure_samples = 1}),
                       rolling),
            0.0)
      << "one sample: the midpoint of the exposure, the capture time itself";
  // Global shutter: the timed render is render(pose) at the timestamp's pose.
  EXPECT_EQ(maxAbsDiff(renderer.render(pose_at, FrameTiming{}), renderer.render(kIdentity)), 0.0);
  EXPECT_EQ(maxAbsDiff(renderer.render(kIdentity, 3.0), renderer.render(kIdentity)), 0.0)
      << "without walkers the time does not matter";
}

/// The mean, in double, of renders of the timing's N sub-exposures made one by one as the
/// header defines them: render(t -> pose_at(t + o_i), {timestamp + o_i, readout}).
cv::Mat meanOfSubExposures(const Renderer& renderer, const PoseAt& pose_at,
                           const FrameTiming& timing, int n) {
  cv::Mat sum(renderer.outputSize(), CV_64FC1, cv::Scalar(0));
  for (int i = 0; i < n; ++i) {
    const double o = timing.exposure_s * ((i + 0.5) / n - 0.5);
    const cv::Mat sub = renderer.render([&](double t) { return pose_at(t + o); },
                                        FrameTiming{.timestamp_s = timing.timestamp_s + o,
                                                    .readout_s = timing.readout_s});
    cv::Mat sub64;
    sub.convertTo(sub64, CV_64FC1);
    sum += sub64;
  }
  cv::Mat mean;
  sum.convertTo(mean, CV_32FC1, 1.0 / n);
  return mean;
}

TEST(SynthMotionBlur, IsTheMeanOfTheShiftedSubExposures) {
  Scene scene = Scene::load(kIndoor, SceneKind::kBox);
  scene.walkers = {.count = 3, .speed_m_s = 2.0, .seed = 4};
  const Renderer renderer(scene, Calibration{}, {OutputKind::kOmni, 1});
  const PoseAt pose_at = [](double t) {
    Eigen::Isometry3d T = poseAtTime(kTurn, t);
    T.translation() = Eigen::Vector3d(0.9 * t, -0.3 * t, 0.0);  // 0.95 m/s
    return T;
  };
  for (const int explicit_n : {0, 3}) {
    const FrameTiming timing{.timestamp_s = 0.4, .readout_s = 0.02, .exposure_s = 0.006,
                             .exposure_samples = explicit_n};
    const int n = renderer.exposureSamples(pose_at, timing);
    if (explicit_n > 0) EXPECT_EQ(n, explicit_n);
    else EXPECT_GT(n, 3) << "the motion needs several sub-exposures";
    const cv::Mat blurred = renderer.render(pose_at, timing);
    const cv::Mat expected = meanOfSubExposures(renderer, pose_at, timing, n);
    RecordProperty(explicit_n > 0 ? "explicit_samples" : "auto_samples", n);
    EXPECT_LT(maxAbsDiff(blurred, expected), 1e-4) << n << " samples; grey levels";
    EXPECT_GT(cv::norm(blurred, renderer.render(pose_at, 0.02), cv::NORM_L1) / blurred.total(), 0.1)
        << "blurred differs from the sharp frame";
  }
}

/// Grey levels either side of the vertical edge of edgeTexture().
constexpr double kLeftGrey = 200.0, kRightGrey = 40.0;

/// An equirect texture with one sharp vertical edge along the meridian lon = 0: bright at
/// negative longitudes (right of the photo's centre column), dark at positive ones, and a
/// second edge at lon = 180 deg.
cv::Mat edgeTexture() {
  cv::Mat tex(1024, 2048, CV_32FC1, cv::Scalar(kLeftGrey));
  tex.colRange(0, 1024).setTo(kRightGrey);  // x < W/2: lon > 0
  return tex;
}

/// Centroid and variance (columns) of the step I(u) - I(u + 1) over columns [lo, hi) of a
/// panorama profile; the step sits at u + 0.5.
std::pair<double, double> stepMoments(const std::vector<double>& profile, int lo, int hi) {
  double sum = 0, first = 0, second = 0;
  for (int u = lo; u < hi; ++u) {
    const auto i = static_cast<std::size_t>(u);
    const double d = profile[i] - profile[i + 1];
    sum += d;
    first += d * (u + 0.5);
    second += d * (u + 0.5) * (u + 0.5);
  }
  const double mean = first / sum;
  return {mean, second / sum - mean * mean};
}

TEST(SynthMotionBlur, ASharpEdgeUnderYawBecomesARampOfTheTurnDuringTheExposure) {
  Scene scene;
  scene.texture = edgeTexture();
  Calibration cal;
  cal.panorama.forward_column = 550.0;  // lon = 0 at column 550, the texture's seam at 0
  const Renderer renderer(scene, cal, {OutputKind::kPanorama, 2});
  const double gamma = cal.panorama.gamma();
  // Yaw at a constant rate, global shutter: the edge sweeps w = rate * exposure / gamma
  // columns centred on its position at the timestamp.
  constexpr double kWidth = 20.3;  // columns
  constexpr double kExposure = 0.01;
  const double rate = kWidth * gamma / kExposure;  // 11.6 rad/s
  const PoseAt pose_at = [&](double t) { return rotation({0, 0, rate * t}); };
  const FrameTiming timing{.exposure_s = kExposure};
  const int n = renderer.exposureSamples(pose_at, timing);
  EXPECT_EQ(n, 41) << "ceil(w / 0.5 px)";
  const cv::Mat sharp = renderer.render(kIdentity);
  const cv::Mat blurred = renderer.render(pose_at, timing);

  const int lo = 520, hi = 580;  // the edge at column 550, w / 2 = 10 columns either side
  std::vector<double> sharp_profile(1100, 0.0), blurred_profile(1100, 0.0);
  for (int v = 0; v < sharp.rows; ++v) {
    for (int u = 0; u < sharp.cols; ++u) {
      sharp_profile[static_cast<std::size_t>(u)] += sharp.at<float>(v, u) / sharp.rows;
      blurred_profile[static_cast<std::size_t>(u)] += blurred.at<float>(v, u) / sharp.rows;
    }
    // Away from the ramp (and its pixel footprint) every sub-exposure sees the same grey.
    for (int u : {lo, lo + 5, hi - 5, hi}) {
      EXPECT_NEAR(blurred.at<float>(v, u), sharp.at<float>(v, u), 1e-3) << v << ", " << u;
    }
  }
  EXPECT_NEAR(sharp_profile[lo], kLeftGrey, 1e-3);
  EXPECT_NEAR(sharp_profile[hi], kRightGrey, 1e-3);
  const auto [sharp_centre, sharp_var] = stepMoments(sharp_profile, lo, hi);
  const auto [blurred_centre, blurred_var] = stepMoments(blurred_profile, lo, hi);
  EXPECT_NEAR(sharp_centre, 550.0, 0.02) << "the sharp edge at lon = 0";
  EXPECT_NEAR(blurred_centre, sharp_centre, 0.02) << "symmetric about the timestamp";
  // The blurred step is the sharp one spread over N equally spaced shifts spanning w (w/N
  // apart): its variance grows by w^2 (N^2 - 1) / (12 N^2); a ramp of width w.
  const double width = std::sqrt(12.0 * (blurred_var - sharp_var) * n * n / (n * n - 1.0));
  RecordProperty("ramp_width_columns", std::to_string(width));
  EXPECT_NEAR(width, kWidth, 0.01 * kWidth) << "columns";
  // The ramp is linear: the middle half falls by (200 - 40) / w per column.
  const double slope = (blurred_profile[545] - blurred_profile[555]) / 10.0;
  EXPECT_NEAR(slope, (kLeftGrey - kRightGrey) / kWidth, 0.03 * (kLeftGrey - kRightGrey) / kWidth);
}

TEST(SynthMotionBlur, SampleCountFollowsTheMotion) {
  const Renderer renderer(Scene::load(kIndoor, SceneKind::kSphere), Calibration{},
                          {OutputKind::kOmni, 1});
  const PoseAt still = [](double) { return kIdentity; };
  EXPECT_EQ(renderer.exposureSamples(still, {.exposure_s = 0.03}), 1) << "nothing moves";
  EXPECT_EQ(renderer.exposureSamples(still, {.exposure_s = 0.03, .exposure_samples = 7}), 7);
  // Omni: P = max(radius_outer, radial scale); a yaw turns the outer edge of the ring by
  // 300 px per radian. The radial scale of the default lens is smaller: 180 px over the
  // ring's elevations, +-atan(55 gamma) = +-0.305 rad, 295 px/rad.
  const double rate = 2.0;  // rad/s
  const PoseAt yaw = [&](double t) { return rotation({0, 0, rate * t}); };
  EXPECT_EQ(renderer.exposureSamples(yaw, {.exposure_s = 0.004}),
            static_cast<int>(std::ceil(300.0 * rate * 0.004 / 0.5)));  // 2.4 px -> 5
  EXPECT_EQ(renderer.exposureSamples(yaw, {.exposure_s = 0.5}), kMaxAutoExposureSamples);
  try {
    (void)renderer.render(yaw, FrameTiming{.exposure_s = -0.01, .exposure_samples = 999});
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(e.what(), HasSubstr("exposure_s: must be"));
    EXPECT_THAT(e.what(), HasSubstr("exposure_samples: must be in [0, 256]"));
  }
}

// ---------------------------------------------------------------------- walkers

TEST(SynthWalkers, DrawsAreSeededPerPersonAndFollowTheirDefinition) {
  const Walkers options{.count = 20, .speed_m_s = 1.4, .min_distance_m = 1.2,
                        .max_distance_m = 2.2, .seed = 5};
  const std::vector<Walker> people = drawWalkers(options, -1.0);
  ASSERT_EQ(people.size(), 20u);
  int counter_clockwise = 0;
  for (const Walker& w : people) {
    EXPECT_GE(w.distance_m, 1.2);
    EXPECT_LE(w.distance_m, 2.2);
    EXPECT_GE(w.azimuth0_rad, 0.0);
    EXPECT_LT(w.azimuth0_rad, 2 * kPi);
    EXPECT_DOUBLE_EQ(std::abs(w.rate_rad_s) * w.distance_m, 1.4) << "walking speed";
    counter_clockwise += w.rate_rad_s > 0;
    EXPECT_EQ(w.radius_m, 0.25);
    EXPECT_EQ(w.base_z, -1.0) << "the floor";
    EXPECT_DOUBLE_EQ(w.top_z, 0.7);
    // Axis on its circle at every time, azimuth advancing at the rate.
    for (const double t : {0.0, 0.7, -2.0}) {
      const Eigen::Vector2d p = w.position(t);
      EXPECT_NEAR(p.norm(), w.distance_m, 1e-12);
      EXPECT_NEAR(std::remainder(std::atan2(p.y(), p.x()) - w.azimuth0_rad - w.rate_rad_s * t,
                                 2 * kPi),
                  0.0, 1e-12);
    }
    for (double f = 0.0; f <= 1.0; f += 0.05) {
      for (double a = -kPi; a < kPi; a += 0.3) {
        EXPECT_GE(w.grey(a, f), 16.0);
        EXPECT_LE(w.grey(a, f), 240.0);
      }
    }
  }
  EXPECT_GT(counter_clockwise, 3) << "random directions";
  EXPECT_LT(counter_clockwise, 17) << "random directions";
  // Person i depends on (seed, i) alone; another seed draws other people.
  Walkers fewer = options;
  fewer.count = 2;
  const std::vector<Walker> two = drawWalkers(fewer, -1.0);
  EXPECT_EQ(two[1].azimuth0_rad, people[1].azimuth0_rad);
  EXPECT_EQ(two[1].band_grey, people[1].band_grey);
  fewer.seed = 6;
  EXPECT_NE(drawWalkers(fewer, -1.0)[1].azimuth0_rad, people[1].azimuth0_rad);
  EXPECT_NE(people[0].band_grey, people[1].band_grey) << "each person its own texture";
  EXPECT_EQ(drawWalkers({.count = 1, .base_z = 0.2}, -1.0)[0].base_z, 0.2);
}

/// Whether panorama pixel (u, v) of a camera at `camera` (world position, level, looking
/// along world +x) sees walker w at time t, by plane geometry: the column's azimuth theta
/// passes the axis (horizontal distance D, azimuth phi) at the angle delta = theta - phi; it
/// meets the cylinder if D |sin delta| <= r, entering at horizontal distance
/// s = D cos delta - sqrt(r^2 - D^2 sin^2 delta), at height camera_z + h(v) s. Returns
/// nullopt when the pixel lies within 1e-7 (relative) of the silhouette's edge.
std::optional<bool> seesWalker(const PanoramaGeometry& g, const Eigen::Vector3d& camera,
                               const Walker& w, double t, int u, int v) {
  const Eigen::Vector2d axis = w.position(t) - camera.head<2>();
  const double distance = axis.norm();
  const double delta = std::remainder(g.azimuth(u) - std::atan2(axis.y(), axis.x()), 2 * kPi);
  const double miss = distance * std::abs(std::sin(delta)) - w.radius_m;
  if (std::abs(miss) < 1e-7) return std::nullopt;
  if (miss > 0 || std::cos(delta) <= 0) return false;
  const double across = distance * std::sin(delta);
  const double s =
      distance * std::cos(delta) - std::sqrt(w.radius_m * w.radius_m - across * across);
  const double z = camera.z() + g.cylinderHeight(v) * s;
  if (std::abs(z - w.base_z) < 1e-7 || std::abs(z - w.top_z) < 1e-7) return std::nullopt;
  return z >= w.base_z && z <= w.top_z;
}

/// Compares row v of a panorama (black scene: walker pixels are > 0) against seesWalker for
/// every walker at time t; returns the number of mismatching pixels.
int mismatches(const cv::Mat& pano, const Renderer& renderer, const Eigen::Vector3d& camera,
               double t, int v) {
  int wrong = 0;
  for (int u = 0; u < pano.cols; ++u) {
    bool expected = false, edge = false;
    for (const Walker& w : renderer.walkers()) {
      const std::optional<bool> sees =
          seesWalker(renderer.calibration().panorama, camera, w, t, u, v);
      edge |= !sees.has_value();
      expected |= sees.value_or(false);
    }
    if (!edge && (pano.at<float>(v, u) > 0.0f) != expected) ++wrong;
  }
  return wrong;
}

/// The occupied columns of row v (walker pixels > 0) as the circular mean column.
double occupiedCentre(const cv::Mat& pano, int v) {
  double c = 0, s = 0;
  for (int u = 0; u < pano.cols; ++u) {
    if (pano.at<float>(v, u) <= 0.0f) continue;
    c += std::cos(2 * kPi * u / pano.cols);
    s += std::sin(2 * kPi * u / pano.cols);
  }
  return std::atan2(s, c) / (2 * kPi) * pano.cols;
}

TEST(SynthWalkers, OccupyTheirSilhouetteInAPanoramaOfEitherScene) {
  for (const SceneKind kind : {SceneKind::kSphere, SceneKind::kBox}) {
    SCOPED_TRACE(toString(kind));
    Scene scene = blankScene(kind);
    scene.walkers = {.count = 2, .width_m = 0.6, .seed = 3};
    const Renderer renderer(scene, Calibration{}, {OutputKind::kPanorama, 1});
    // Box: the camera away from the origin (it may translate in a room).
    const Eigen::Vector3d camera =
        kind == SceneKind::kBox ? Eigen::Vector3d(0.4, -0.3, 0.1) : Eigen::Vector3d::Zero();
    const cv::Mat pano = renderer.render(translation(camera), 0.0);
    int wrong = 0;
    for (int v = 0; v < pano.rows; ++v) wrong += mismatches(pano, renderer, camera, 0.0, v);
    const int seen = cv::countNonZero(pano > 0);
    EXPECT_EQ(wrong, 0) << "of " << seen << " walker pixels";
    EXPECT_GT(seen, 2000);
    // On the horizon row each walker covers the azimuths within asin(r / D) of its axis.
    const int horizon = 54;
    for (const Walker& w : renderer.walkers()) {
      const Eigen::Vector2d axis = w.position(0.0) - camera.head<2>();
      const double half = std::asin(w.radius_m / axis.norm());
      const double centre = renderer.calibration().panorama.column(std::atan2(axis.y(), axis.x()));
      int inside = 0;
      for (int du = -60; du <= 60; ++du) {
        const int u = ((static_cast<int>(std::lround(centre)) + du) % 1100 + 1100) % 1100;
        const double off =
            std::remainder(u - centre, 1100.0) * renderer.calibration().panorama.gamma();
        if (std::abs(off) < half) {
          ++inside;
          EXPECT_GT(pano.at<float>(horizon, u), 0.0f) << "column " << u;
        }
      }
      EXPECT_NEAR(inside, 2 * half / renderer.calibration().panorama.gamma(), 1.0);
    }
  }
}

TEST(SynthWalkers, MoveBySpeedTimesTimeAlongTheirCircle) {
  Scene scene = blankScene(SceneKind::kSphere);
  scene.walkers = {.count = 1, .speed_m_s = 1.5, .min_distance_m = 2.0, .max_distance_m = 2.0,
                   .seed = 8};
  const Renderer renderer(scene, Calibration{}, {OutputKind::kPanorama, 1});
  const Walker& w = renderer.walkers().front();
  const double gamma = renderer.calibration().panorama.gamma();
  const cv::Mat before = renderer.render(kIdentity, 1.0);
  const cv::Mat after = renderer.render(kIdentity, 1.4);
  for (int v = 0; v < before.rows; v += 9) {
    EXPECT_EQ(mismatches(before, renderer, Eigen::Vector3d::Zero(), 1.0, v), 0) << v;
    EXPECT_EQ(mismatches(after, renderer, Eigen::Vector3d::Zero(), 1.4, v), 0) << v;
  }
  // 1.5 m/s * 0.4 s along a 2 m circle: 0.3 rad = 52.5 columns, in the walker's direction.
  const double moved =
      std::remainder(occupiedCentre(after, 54) - occupiedCentre(before, 54), 1100.0);
  EXPECT_NEAR(std::abs(moved), 1.5 * 0.4 / 2.0 / gamma, 1.0);
  EXPECT_EQ(moved > 0, w.rate_rad_s > 0) << "panorama columns grow with the azimuth";
  EXPECT_NEAR(moved * gamma, w.rate_rad_s * 0.4, 1.0 * gamma);
}

TEST(SynthWalkers, RollingShutterRowsSeeThemAtTheirCaptureTimes) {
  Scene scene = blankScene(SceneKind::kSphere);
  scene.walkers = {.count = 1, .speed_m_s = 6.0, .min_distance_m = 2.0, .max_distance_m = 2.0,
                   .seed = 2};
  const Renderer renderer(scene, Calibration{}, {OutputKind::kPanorama, 1});
  const PoseAt still = [](double) { return kIdentity; };
  constexpr double kStamp = 2.5, kReadout = 0.03;
  const cv::Mat pano =
      renderer.render(still, FrameTiming{.timestamp_s = kStamp, .readout_s = kReadout});
  const int rows = pano.rows;
  for (int v = 0; v < rows; ++v) {
    const double t = kStamp + rowTime(v, rows, kReadout);
    EXPECT_EQ(mismatches(pano, renderer, Eigen::Vector3d::Zero(), t, v), 0) << "row " << v;
    if (v % 20 == 0) {
      EXPECT_EQ(maxAbsDiff(pano.row(v), renderer.render(kIdentity, t).row(v)), 0.0) << v;
    }
  }
  // 3 rad/s over 109/110 of a 30 ms readout: the last row sees it 15.5 columns further on.
  const double moved =
      std::remainder(occupiedCentre(pano, rows - 1) - occupiedCentre(pano, 0), 1100.0);
  const double expected = renderer.walkers().front().rate_rad_s * kReadout * (rows - 1) / rows /
                          renderer.calibration().panorama.gamma();
  EXPECT_NEAR(moved, expected, 1.0);
  EXPECT_GT(std::abs(moved), 10.0);
}

TEST(SynthWalkers, NoneLeaveEveryRenderUnchanged) {
  Scene plain = Scene::load(kIndoor, SceneKind::kBox);
  Scene none = plain;
  none.walkers = {.count = 0, .width_m = 1.0, .speed_m_s = 3.0, .seed = 11};
  for (const OutputKind output : {OutputKind::kOmni, OutputKind::kPanorama}) {
    const Renderer a(plain, Calibration{}, {output, 1});
    const Renderer b(none, Calibration{}, {output, 1});
    ASSERT_TRUE(b.walkers().empty());
    const PoseAt pose_at = [](double t) {
      Eigen::Isometry3d T = poseAtTime(kTurn, t);
      T.translation() = Eigen::Vector3d(t, 0.0, 0.0);
      return T;
    };
    const Eigen::Isometry3d T = pose_at(0.01);
    EXPECT_EQ(maxAbsDiff(a.render(T), b.render(T)), 0.0);
    EXPECT_EQ(maxAbsDiff(a.render(T), b.render(T, 4.0)), 0.0);
    EXPECT_EQ(maxAbsDiff(a.render(pose_at, 0.02), b.render(pose_at, 0.02)), 0.0);
    EXPECT_EQ(maxAbsDiff(a.render(pose_at, 0.02),
                         b.render(pose_at, FrameTiming{.timestamp_s = 9.0, .readout_s = 0.02})),
              0.0);
  }
}

TEST(SynthWalkers, InvalidOptionsAreRejectedNamingTheField) {
  const Walkers bad{.count = -1, .width_m = 0.0, .height_m = -1.0, .base_z = NAN,
                    .speed_m_s = 50.0, .min_distance_m = 3.0, .max_distance_m = 2.0};
  const std::vector<std::string> p = bad.validate();
  const auto has = [&](const std::vector<std::string>& list, const std::string& text) {
    return std::any_of(list.begin(), list.end(),
                       [&](const std::string& s) { return s.find(text) == 0; });
  };
  for (const char* field :
       {"walkers.count: ", "walkers.width_m: ", "walkers.height_m: ", "walkers.base_z: ",
        "walkers.speed_m_s: ", "walkers.max_distance_m: "}) {
    EXPECT_TRUE(has(p, field)) << field;
  }
  EXPECT_TRUE(has(Walkers{.width_m = 1.0, .min_distance_m = 0.4}.validate(),
                  "walkers.min_distance_m: ")) << "a walker covering the origin";
  EXPECT_TRUE(Walkers{.count = 3}.validate(SceneKind::kBox, Box{}).empty());
  // Box room 6 x 5 m, floor -1, ceiling 1.5: walkers must stay inside.
  const Walkers wide{.count = 3, .width_m = 0.6, .min_distance_m = 2.0, .max_distance_m = 2.3};
  EXPECT_TRUE(wide.validate(SceneKind::kSphere, Box{}).empty()) << "no room at infinity";
  EXPECT_TRUE(has(wide.validate(SceneKind::kBox, Box{}), "walkers.max_distance_m: 2.3 m"));
  EXPECT_TRUE(has(Walkers{.count = 1, .height_m = 2.6}.validate(SceneKind::kBox, Box{}),
                  "walkers.height_m: the top (1.6 m) is above the ceiling"));
  EXPECT_TRUE(has(Walkers{.count = 1, .base_z = -1.5}.validate(SceneKind::kBox, Box{}),
                  "walkers.base_z: -1.5 m is below the floor"));
  Scene scene = blankScene(SceneKind::kBox);
  scene.walkers = wide;
  try {
    (void)Renderer(scene, Calibration{}, {});
    FAIL() << "expected std::invalid_argument";
  } catch (const std::invalid_argument& e) {
    EXPECT_THAT(e.what(), HasSubstr("scene.walkers.max_distance_m"));
  }
  EXPECT_THROW(drawWalkers(bad, -1.0), std::invalid_argument);
  // The command-line form.
  const Walkers parsed = parseWalkers("4,0.4,1.8,0.9");
  EXPECT_EQ(parsed.count, 4);
  EXPECT_EQ(parsed.width_m, 0.4);
  EXPECT_EQ(parsed.height_m, 1.8);
  EXPECT_EQ(parsed.speed_m_s, 0.9);
  EXPECT_EQ(parseWalkers("2", {.speed_m_s = 0.3}).speed_m_s, 0.3) << "fields not given are kept";
  for (const char* text : {"", "x", "2.5", "3,0", "1,2,3,4,5", "3,0.5,abc", "1e999", "101"}) {
    EXPECT_THROW(parseWalkers(text), std::invalid_argument) << text;
  }
  const auto parse_error = [](const std::string& text) -> std::string {
    try {
      parseWalkers(text);
    } catch (const std::invalid_argument& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_THAT(parse_error("3,0"), HasSubstr("walkers.width_m"));
  EXPECT_THAT(parse_error("3,0.5,abc"), HasSubstr("'abc' is not a number"));
}

TEST(SynthWalkers, MotionScriptsReadThemWithTheirPath) {
  const MotionScript script = MotionScript::parse(
      "walkers: {count: 3, width_m: 0.4, height_m: 1.8, base_z: -0.9, speed_m_s: 0.8,\n"
      "          distance_m: [1.6, 1.9], seed: 12}\n"
      "segments: [{frames: 3}]\n");
  ASSERT_TRUE(script.walkers);
  EXPECT_EQ(script.walkers->count, 3);
  EXPECT_EQ(script.walkers->width_m, 0.4);
  EXPECT_EQ(script.walkers->height_m, 1.8);
  EXPECT_EQ(script.walkers->base_z, -0.9);
  EXPECT_EQ(script.walkers->speed_m_s, 0.8);
  EXPECT_EQ(script.walkers->min_distance_m, 1.6);
  EXPECT_EQ(script.walkers->max_distance_m, 1.9);
  EXPECT_EQ(script.walkers->seed, 12u);
  EXPECT_FALSE(MotionScript::parse("segments: [{frames: 3}]\n").walkers);
  const MotionScript example = MotionScript::load(kSourceDir / "tools/synth/examples/people.yaml");
  ASSERT_TRUE(example.walkers);
  EXPECT_EQ(example.walkers->count, 4);
  EXPECT_TRUE(example.walkers->validate(SceneKind::kBox, Box{}).empty());
  const auto error = [](const std::string& walkers) -> std::string {
    try {
      MotionScript::parse("walkers: " + walkers + "\nsegments: [{frames: 3}]\n", "w.yaml");
    } catch (const MotionError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_THAT(error("{count: 2, legs: 2}"), HasSubstr("w.yaml: walkers.legs: unknown key"));
  EXPECT_THAT(error("{count: many}"), HasSubstr("w.yaml: walkers.count: cannot read 'many'"));
  EXPECT_THAT(error("{count: 2, speed_m_s: -1}"),
              HasSubstr("w.yaml: walkers.speed_m_s: must be in"));
  EXPECT_THAT(error("{distance_m: [2, 1]}"), HasSubstr("w.yaml: walkers.max_distance_m:"));
  EXPECT_THAT(error("3"), HasSubstr("w.yaml: walkers: must be a map"));
}

// ---------------------------------------------------------------------- auto-exposure steps

TEST(SynthDegrade, AutoExposureStepsFollowTheirDefinition) {
  const DegradeOptions options{.seed = 9, .exposure_step = 0.25, .exposure_step_every = 5,
                               .exposure_step_levels = 2};
  std::vector<double> gain;
  for (std::uint64_t k = 0; k < 300; ++k) gain.push_back(exposureStepGain(options, k));
  std::vector<int> level;
  for (const double g : gain) {
    const int n = static_cast<int>(std::lround(std::log(g) / std::log(1.25)));
    EXPECT_EQ(g, std::pow(1.25, n)) << "a whole number of x1.25 steps";
    EXPECT_LE(std::abs(n), 2);
    level.push_back(n);
  }
  int up = 0, down = 0;
  std::vector<int> visits(5, 0);
  for (std::size_t k = 0; k < level.size(); ++k) {
    ++visits[static_cast<std::size_t>(level[k] + 2)];
    if (k < 5) {
      EXPECT_EQ(level[k], 0) << "the first step is at frame 5";
      continue;
    }
    const int change = level[k] - level[k - 1];
    if (k % 5 != 0) {
      EXPECT_EQ(change, 0) << k;
    } else {
      EXPECT_EQ(std::abs(change), 1) << "one step at frame " << k;
      up += change > 0;
      down += change < 0;
    }
  }
  EXPECT_EQ(up + down, 59);
  EXPECT_GT(up, 15);
  EXPECT_GT(down, 15);
  for (int v : visits) EXPECT_GT(v, 0) << "every level of the range is used";
  // A frame's gain depends on (seed, frame) only: alone, in any order, whatever the other
  // degradations are; another seed steps otherwise.
  DegradeOptions noisy = options;
  noisy.noise_sigma = 3.0;
  noisy.exposure_gain_std = 0.1;
  for (const std::uint64_t k : {299u, 7u, 150u, 0u, 55u}) {
    EXPECT_EQ(exposureStepGain(noisy, k), gain[k]) << k;
  }
  DegradeOptions other = options;
  other.seed = 10;
  int differ = 0;
  for (std::uint64_t k = 0; k < 300; ++k) differ += exposureStepGain(other, k) != gain[k];
  EXPECT_GT(differ, 50);
  // Without steps the gain is 1.
  EXPECT_EQ(exposureStepGain({.exposure_step = 0.25}, 100), 1.0);
  EXPECT_EQ(exposureStepGain({.exposure_step_every = 3}, 100), 1.0);
  // Regression guard of the draws (cv::RNG seeded by (seed 9, frame)), recorded from this
  // implementation: the levels after the first eight steps. A change means every dataset
  // rendered with exposure steps changes.
  std::vector<int> first_steps;
  for (int m = 1; m <= 8; ++m) first_steps.push_back(level[static_cast<std::size_t>(5 * m)]);
  EXPECT_EQ(first_steps, (std::vector<int>{-1, 0, -1, 0, -1, 0, -1, -2}));
}

TEST(SynthDegrade, AutoExposureStepsScaleTheImage) {
  const DegradeOptions options{.seed = 2, .exposure_step = 0.25, .exposure_step_every = 1};
  cv::Mat flat(16, 16, CV_32FC1, cv::Scalar(100.0));
  cv::Mat ramp(16, 16, CV_32FC1);
  for (int y = 0; y < ramp.rows; ++y)
    for (int x = 0; x < ramp.cols; ++x)
      ramp.at<float>(y, x) = static_cast<float>(10 + 0.7 * (16 * y + x));
  for (std::uint64_t k = 0; k < 12; ++k) {
    const double g = exposureStepGain(options, k);
    // 100 * 1.25^n for |n| <= 2 is 64, 80, 100, 125 or 156.25: no rounding ties.
    const cv::Mat out = degrade(flat, options, k);
    EXPECT_EQ(cv::countNonZero(out != cv::saturate_cast<uchar>(100.0 * g)), 0)
        << k << " gain " << g;
    cv::Mat expected;
    cv::Mat(ramp * g).convertTo(expected, CV_8UC1);
    EXPECT_LE(cv::norm(degrade(ramp, options, k), expected, cv::NORM_INF), 1.0) << k;
  }
  const auto problem = [](const DegradeOptions& o) {
    const auto p = o.validate();
    return p.empty() ? std::string() : p.front();
  };
  EXPECT_EQ(problem({.exposure_step = 1.5}).rfind("exposure_step: ", 0), 0u);
  EXPECT_EQ(problem({.exposure_step_every = -1}).rfind("exposure_step_every: ", 0), 0u);
  EXPECT_EQ(problem({.exposure_step_levels = 0}).rfind("exposure_step_levels: ", 0), 0u);
  EXPECT_THROW(exposureStepGain({.exposure_step = -0.1}, 3), std::invalid_argument);
}

// ---------------------------------------------------------------------- vignetting

TEST(SynthVignetting, IsItsFormulaAtSeveralPixels) {
  const Calibration cal;  // centre (359.5, 359.5), radius_outer 300
  const Vignetting vignetting{0.6};
  cv::Mat image(720, 720, CV_32FC1);
  cv::randu(image, 0.0, 255.0);
  cv::Mat out = image.clone();
  vignetting.apply(out, cal, OutputKind::kOmni);
  const auto expected = [&](int x, int y) {
    const double r = std::hypot(x - 359.5, y - 359.5);
    const double factor = std::max(0.0, 1.0 - 0.6 * (r / 300.0) * (r / 300.0));
    return image.at<float>(y, x) * static_cast<float>(factor);
  };
  const std::vector<std::pair<int, int>> pixels = {{359, 359}, {479, 360}, {659, 359}, {359, 59},
                                                   {150, 600}, {0, 0},     {719, 719}, {600, 100}};
  for (const auto& [x, y] : pixels) {
    EXPECT_NEAR(out.at<float>(y, x), expected(x, y), 1e-4) << x << ", " << y;
  }
  EXPECT_EQ(out.at<float>(0, 0), 0.0f) << "the corner: the parabola clamped at 0";
  EXPECT_NEAR(vignetting.factor(cal, 659.5, 359.5), 0.4, 1e-12) << "1 - strength at radius_outer";
  EXPECT_EQ(vignetting.factor(cal, 359.5, 359.5), 1.0);

  // Panorama: the factor of the omni pixel each panorama pixel is unwrapped from; for the
  // linear lens (outer edge at the top) radius r(v) = r_out - (v + 0.5) (r_out - r_in) / H.
  cv::Mat pano(cal.panorama.size(), CV_32FC1);
  cv::randu(pano, 0.0, 255.0);
  cv::Mat pano_out = pano.clone();
  vignetting.apply(pano_out, cal, OutputKind::kPanorama);
  const std::vector<std::pair<int, int>> pano_pixels = {{0, 0}, {300, 54}, {1099, 109}, {777, 80}};
  for (const auto& [u, v] : pano_pixels) {
    const double r = 300.0 - (v + 0.5) * 180.0 / 110.0;
    EXPECT_NEAR(pano_out.at<float>(v, u),
                pano.at<float>(v, u) * static_cast<float>(1.0 - 0.6 * (r / 300.0) * (r / 300.0)),
                1e-4) << u << ", " << v;
  }

  EXPECT_FALSE(Vignetting{1.5}.validate().empty());
  EXPECT_EQ(Vignetting{-0.1}.validate().front().rfind("vignetting strength: ", 0), 0u);
  cv::Mat small(10, 10, CV_32FC1);
  EXPECT_THROW(vignetting.apply(small, cal, OutputKind::kOmni), std::invalid_argument);
  EXPECT_THROW(Vignetting{2.0}.apply(out, cal, OutputKind::kOmni), std::invalid_argument);
}

TEST(SynthVignetting, UnwrappedOmniMatchesTheVignettedPanorama) {
  const Calibration cal;
  const Scene scene = Scene::load(kIndoor, SceneKind::kSphere);
  cv::Mat omni = Renderer(scene, cal, {OutputKind::kOmni, 2}).render(kIdentity);
  cv::Mat pano = Renderer(scene, cal, {OutputKind::kPanorama, 2}).render(kIdentity);
  const Vignetting vignetting{0.8};
  vignetting.apply(omni, cal, OutputKind::kOmni);
  vignetting.apply(pano, cal, OutputKind::kPanorama);
  const cv::Mat unwrapped = testing::pointSampledUnwrap(omni, cal);
  const cv::Rect inner(0, 2, pano.cols, pano.rows - 4);
  EXPECT_LT(cv::mean(cv::abs(unwrapped(inner) - pano(inner)))[0], 1.0) << "grey levels";
}

}  // namespace
}  // namespace omnipose::synth
