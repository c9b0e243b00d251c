// Each window's vertical scale alone (src/pipeline/vertical_scale.hpp, private): exact
// vertical warps of a texture, masked columns, unrelated content, and against the exact
// renderer, a forward step in the box room whose every window's vertical expansion the room's
// geometry gives.

#include "pipeline/vertical_scale.hpp"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/synth/synth.hpp"
#include "omnipose/window_registration.hpp"
#include "render_fixture.hpp"
#include "test_figures.hpp"

namespace omnipose {
namespace {

using pipeline::VerticalScale;

constexpr int kWindow = 110, kStep = 20;

class VerticalScaleTest : public ::testing::Test {
 protected:
  VerticalScaleTest()
      : geometry_(Calibration{}.panorama),
        width_(geometry_.width),
        height_(geometry_.height),
        validity_(height_, width_, CV_32FC1, cv::Scalar(1.0f)) {
    for (int k = 0; k * kStep < width_; ++k) centers_.push_back(k * kStep + 0.5 * (kWindow - 1));
  }

  /// Texture of grey levels around 128 with detail at a few pixels' scale, periodic in u
  /// (blurred with its columns wrapped).
  cv::Mat texture(int seed) const {
    cv::Mat t(height_, width_ + 40, CV_32FC1);
    cv::RNG rng(static_cast<std::uint64_t>(seed));
    rng.fill(t, cv::RNG::UNIFORM, 0.0, 255.0);
    t(cv::Rect(0, 0, 40, height_)).copyTo(t(cv::Rect(width_, 0, 40, height_)));
    cv::GaussianBlur(t, t, cv::Size(0, 0), 1.5);
    cv::Mat out = t(cv::Rect(20, 0, width_, height_)).clone();
    t(cv::Rect(width_, 0, 20, height_)).copyTo(out(cv::Rect(0, 0, 20, height_)));
    return (out - 128.0f) * 3.0f + 128.0f;
  }

  /// current(u, y) = reference(u + du, yc + dv + s (y - yc)), bilinear, columns wrapping,
  /// rows clamped (yc the windows' centre row): what a window with vertical scale s and shift
  /// (du, dv) sees.
  cv::Mat warped(const cv::Mat& reference, double du, double dv, double s) const {
    cv::Mat out(reference.size(), CV_32FC1);
    const double yc = 0.5 * (kWindow - 1);
    for (int y = 0; y < height_; ++y) {
      const double v = std::clamp(yc + dv + s * (y - yc), 0.0, height_ - 1.001);
      const int v0 = static_cast<int>(v);
      const double fv = v - v0;
      for (int u = 0; u < width_; ++u) {
        const double x = u + du;
        const int x0 = static_cast<int>(std::floor(x));
        const double fx = x - x0;
        const auto at = [&](int row, int col) {
          return static_cast<double>(
              reference.at<float>(row, ((col % width_) + width_) % width_));
        };
        out.at<float>(y, u) = static_cast<float>(
            (1 - fv) * ((1 - fx) * at(v0, x0) + fx * at(v0, x0 + 1)) +
            fv * ((1 - fx) * at(v0 + 1, x0) + fx * at(v0 + 1, x0 + 1)));
      }
    }
    return out;
  }

  /// Windows as the registration reports them: every one valid with peaks, shift (du, dv).
  std::vector<WindowMotion> windows(double du, double dv) const {
    std::vector<WindowMotion> w(centers_.size());
    for (std::size_t k = 0; k < w.size(); ++k) {
      w[k].center_u = std::fmod(centers_[k], width_);
      w[k].du = du;
      w[k].dv = dv;
      w[k].confidence = 0.8;
      w[k].rs_confidence = 0.5;
      w[k].valid = true;
    }
    return w;
  }

  VerticalScale meter(int workers = 1) const {
    return VerticalScale(validity_, kWindow, 0, centers_, workers);
  }

  PanoramaGeometry geometry_;
  int width_, height_;
  cv::Mat validity_;
  std::vector<double> centers_;
};

TEST_F(VerticalScaleTest, RecoversAnExactVerticalScaleInEveryWindow) {
  const cv::Mat reference = texture(1);
  runtime::WorkerPool pool(1);
  for (const double s : {0.97, 1.0, 1.03}) {
    const double du = 2.4, dv = 0.7;
    const cv::Mat current = warped(reference, du, dv, s);
    std::vector<WindowMotion> w = windows(du, dv);
    meter().measure(reference, current, w, pool);
    for (std::size_t k = 0; k < w.size(); ++k) {
      ASSERT_GT(w[k].vertical_scale_sigma, 0.0) << "s " << s << " window " << k;
      EXPECT_NEAR(std::log(w[k].vertical_scale), std::log(s), 1.5e-3)
          << "s " << s << " window " << k;
      EXPECT_LT(w[k].vertical_scale_sigma, 2e-3) << "s " << s << " window " << k;
      // The registration's own fields are left as they were.
      EXPECT_EQ(w[k].scale, 1.0);
      EXPECT_EQ(w[k].du, du);
    }
  }
}

TEST_F(VerticalScaleTest, TheSameOnAnyNumberOfWorkers) {
  const cv::Mat reference = texture(2);
  const cv::Mat current = warped(reference, -1.3, 0.4, 0.985);
  std::vector<WindowMotion> one = windows(-1.3, 0.4), two = windows(-1.3, 0.4);
  runtime::WorkerPool pool1(1), pool2(2);
  meter(1).measure(reference, current, one, pool1);
  meter(2).measure(reference, current, two, pool2);
  for (std::size_t k = 0; k < one.size(); ++k) {
    EXPECT_EQ(one[k].vertical_scale, two[k].vertical_scale) << k;
    EXPECT_EQ(one[k].vertical_scale_sigma, two[k].vertical_scale_sigma) << k;
  }
}

TEST_F(VerticalScaleTest, WindowsWithoutPeaksAndForeignPanoramasAreNotMeasured) {
  const cv::Mat reference = texture(3);
  const cv::Mat current = warped(reference, 1.0, 0.0, 0.98);
  runtime::WorkerPool pool(1);
  std::vector<WindowMotion> w = windows(1.0, 0.0);
  w[0].valid = false;
  w[1].rs_confidence = 0.0;
  w[2].confidence = 0.0;
  w[3].du = std::numeric_limits<double>::quiet_NaN();
  meter().measure(reference, current, w, pool);
  for (int k = 0; k < 4; ++k) {
    EXPECT_EQ(w[k].vertical_scale, 1.0) << k;
    EXPECT_EQ(w[k].vertical_scale_sigma, 0.0) << k;
  }
  EXPECT_GT(w[4].vertical_scale_sigma, 0.0);
  // A panorama of another size or type: nothing measured, the last pass's values cleared.
  const cv::Mat small(height_, width_ / 2, CV_32FC1, cv::Scalar(0));
  meter().measure(reference, small, w, pool);
  cv::Mat bytes;
  current.convertTo(bytes, CV_8U);
  std::vector<WindowMotion> v = windows(1.0, 0.0);
  meter().measure(reference, bytes, v, pool);
  for (std::size_t k = 0; k < w.size(); ++k) {
    EXPECT_EQ(w[k].vertical_scale_sigma, 0.0) << k;
    EXPECT_EQ(v[k].vertical_scale_sigma, 0.0) << k;
  }
  EXPECT_THROW(VerticalScale(validity_, kWindow, 1, centers_, 1), std::invalid_argument);
  EXPECT_THROW(VerticalScale(validity_, kWindow, 0, {}, 1), std::invalid_argument);
  EXPECT_THROW(VerticalScale(validity_, kWindow, 0, centers_, 0), std::invalid_argument);
  EXPECT_THROW(VerticalScale(cv::Mat(height_, width_, CV_8UC1), kWindow, 0, centers_, 1),
               std::invalid_argument);
}

TEST_F(VerticalScaleTest, MaskedColumnsDoNotBiasTheWindowsTheyCross) {
  // A support strut: 24 columns masked, black in both panoramas.
  const double s = 0.975;
  cv::Mat reference = texture(4);
  cv::Mat current = warped(reference, 0.6, -0.3, s);
  const cv::Rect strut(300, 0, 24, height_);
  validity_(strut).setTo(0.0f);
  reference(strut).setTo(0.0f);
  current(strut).setTo(0.0f);
  runtime::WorkerPool pool(1);
  std::vector<WindowMotion> w = windows(0.6, -0.3);
  meter().measure(reference, current, w, pool);
  int crossing = 0;
  for (std::size_t k = 0; k < w.size(); ++k) {
    ASSERT_GT(w[k].vertical_scale_sigma, 0.0) << k;
    EXPECT_NEAR(std::log(w[k].vertical_scale), std::log(s), 2e-3) << k;
    crossing += std::abs(centers_[k] - 312.0) < 0.5 * kWindow ? 1 : 0;
  }
  EXPECT_GE(crossing, 5);
}

TEST_F(VerticalScaleTest, UnrelatedContentIsFarLessCertain) {
  const cv::Mat reference = texture(5);
  runtime::WorkerPool pool(1);
  std::vector<WindowMotion> same = windows(0.0, 0.0), other = windows(0.0, 0.0);
  meter().measure(reference, warped(reference, 0.0, 0.0, 1.01), same, pool);
  meter().measure(reference, texture(6), other, pool);
  std::vector<double> sigma_same, sigma_other;
  for (std::size_t k = 0; k < same.size(); ++k) {
    sigma_same.push_back(same[k].vertical_scale_sigma);
    // Not measured (0) or measured with a much larger sigma.
    if (other[k].vertical_scale_sigma > 0.0) sigma_other.push_back(other[k].vertical_scale_sigma);
  }
  std::sort(sigma_same.begin(), sigma_same.end());
  std::sort(sigma_other.begin(), sigma_other.end());
  ASSERT_FALSE(sigma_same.empty());
  if (!sigma_other.empty()) {
    EXPECT_GT(sigma_other.front(), 5.0 * sigma_same.back());
  }
}

/// The point where the ray from `origin` along `direction` leaves `box` (world frame).
Eigen::Vector3d exitPoint(const synth::Box& box, const Eigen::Vector3d& origin,
                          const Eigen::Vector3d& direction) {
  const Eigen::Vector3d lo(-0.5 * box.length, -0.5 * box.width, box.floor);
  const Eigen::Vector3d hi(0.5 * box.length, 0.5 * box.width, box.ceiling);
  double t = std::numeric_limits<double>::infinity();
  for (int a = 0; a < 3; ++a) {
    if (direction(a) > 0) t = std::min(t, (hi(a) - origin(a)) / direction(a));
    if (direction(a) < 0) t = std::min(t, (lo(a) - origin(a)) / direction(a));
  }
  return origin + t * direction;
}

// The referee: a 5 cm step forward in the box room, off its centre. For each window's centre
// column the room's geometry gives the reference row of every current row (the exit point of
// its bearing, seen from the previous position); the exact vertical scale is the taper-weighted
// least-squares slope of that map. The vertical scale reads it in every window within 60 deg of
// the direction of travel (either end), and more exactly than the log-polar scale.
TEST(VerticalScaleRenderer, ReadsTheBoxRoomsExactVerticalExpansion) {
  if (!std::filesystem::exists(testing::indoorPhoto()))
    GTEST_SKIP() << "missing " << testing::indoorPhoto();
  const Calibration calibration;
  const PanoramaGeometry& g = calibration.panorama;
  synth::RenderOptions o;
  o.output = synth::OutputKind::kPanorama;
  o.supersample = 2;
  const synth::Scene scene = synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kBox);
  const synth::Renderer renderer(scene, calibration, o);
  Eigen::Isometry3d T0 = Eigen::Isometry3d::Identity(), T1 = Eigen::Isometry3d::Identity();
  T0.linear() = rotationFromVector(Eigen::Vector3d(0, 0, 0.4));
  T0.translation() = Eigen::Vector3d(0.8, -0.5, 0.0);
  T1.linear() = T0.linear();
  T1.translation() = T0.translation() + 0.05 * T0.linear().col(0);
  const cv::Mat reference = renderer.render(T0), current = renderer.render(T1);

  WindowRegistration::Options ro;
  WindowRegistration registration(g.size(), ro);
  registration.setReference(reference);
  std::vector<WindowMotion> w(static_cast<std::size_t>(registration.windowCount()));
  ASSERT_TRUE(registration.measure(current, w));
  std::vector<double> centers;
  for (int k = 0; k < registration.windowCount(); ++k)
    centers.push_back(registration.windowCenter(k));
  const cv::Mat validity(g.size(), CV_32FC1, cv::Scalar(1.0f));
  runtime::WorkerPool pool(1);
  VerticalScale(validity, ro.window, registration.windowTop(), centers, 1)
      .measure(reference, current, w, pool);

  double vertical_sq = 0.0, log_polar_sq = 0.0;
  int compared = 0;
  for (int k = 0; k < registration.windowCount(); ++k) {
    // The exact map of the window's centre column: current row y -> reference row.
    const double u = registration.windowCenter(k);
    double sw = 0, sy = 0, sv = 0, syy = 0, syv = 0;
    for (int y = 0; y < ro.window; ++y) {
      const int row = registration.windowTop() + y;
      const Eigen::Vector3d ray = T1.linear() * g.bearing(u, row);
      const Eigen::Vector3d p = exitPoint(scene.box, T1.translation(), ray);
      const Eigen::Vector3d seen = T0.linear().transpose() * (p - T0.translation());
      const double v = g.row(seen.z() / seen.head<2>().norm());
      const double h = windowTaper(y, ro.window);
      sw += h;
      sy += h * y;
      sv += h * v;
      syy += h * y * y;
      syv += h * y * v;
    }
    const double exact = std::log((sw * syv - sy * sv) / (sw * syy - sy * sy));
    const double azimuth = g.azimuth(u);
    if (std::abs(std::cos(azimuth)) < 0.5) continue;
    ASSERT_TRUE(w[k].valid) << k;
    ASSERT_GT(w[k].vertical_scale_sigma, 0.0) << k;
    const double vertical = std::log(w[k].vertical_scale), log_polar = std::log(w[k].scale);
    EXPECT_NEAR(vertical, exact, 0.2 * std::abs(exact) + 1e-3)
        << "window " << k << " azimuth " << azimuth * 180 / std::numbers::pi << " deg";
    vertical_sq += (vertical - exact) * (vertical - exact);
    log_polar_sq += (log_polar - exact) * (log_polar - exact);
    ++compared;
  }
  ASSERT_GE(compared, 20);
  const double vertical_rms = std::sqrt(vertical_sq / compared);
  const double log_polar_rms = std::sqrt(log_polar_sq / compared);
  testing::recordFigure("box_room_ln_s_rms_vertical", vertical_rms, 6);
  testing::recordFigure("box_room_ln_s_rms_log_polar", log_polar_rms, 6);
  EXPECT_LT(vertical_rms, log_polar_rms);
}

}  // namespace
}  // namespace omnipose
