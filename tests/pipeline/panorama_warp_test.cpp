// The de-rotation of the refinement pass (src/pipeline/panorama_warp.hpp), refereed by the
// exact renderer: the current panorama de-rotated by the true rotation is the previous one.

#include "pipeline/panorama_warp.hpp"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "omnipose/so3.hpp"
#include "render_fixture.hpp"

namespace omnipose {
namespace {

/// De-rotates `current` by R with the warp's two stages, as the pipeline does.
cv::Mat derotate(PanoramaWarp& warp, const cv::Mat& current, const Eigen::Matrix3d& R) {
  warp.padCurrent(current);
  warp.projectGridRows(R, 0, warp.gridRows());
  cv::Mat out(current.size(), CV_32FC1);
  warp.derotateRows(out, 0, out.rows);
  return out;
}

/// A panorama of uniform noise in [0, 255) (every column differs from its neighbours, so a
/// shift or a wrong row shows).
cv::Mat randomPanorama(const PanoramaGeometry& geometry) {
  cv::Mat panorama(geometry.height, geometry.width, CV_32FC1);
  cv::randu(panorama, 0.0, 255.0);
  return panorama;
}

/// Mean absolute difference of two panoramas over rows [margin, H - margin), after a light
/// blur of both (the renders are box-filtered, the warp is bicubic).
double meanAbsDifference(const cv::Mat& a, const cv::Mat& b, int margin) {
  cv::Mat ba, bb;
  cv::GaussianBlur(a, ba, cv::Size(0, 0), 1.0);
  cv::GaussianBlur(b, bb, cv::Size(0, 0), 1.0);
  const cv::Rect inner(0, margin, a.cols, a.rows - 2 * margin);
  return cv::mean(cv::abs(ba(inner) - bb(inner)))[0];
}

TEST(PanoramaWarp, CurrentRenderDerotatedByTheTrueRotationIsThePreviousRender) {
  if (!std::filesystem::exists(testing::indoorPhoto())) GTEST_SKIP() << "missing photo";
  Calibration c;
  const auto scene = synth::Scene::load(testing::indoorPhoto(), synth::SceneKind::kSphere);
  synth::RenderOptions options;
  options.output = synth::OutputKind::kPanorama;
  options.supersample = 2;
  const synth::Renderer renderer(scene, c, options);
  // Roll, pitch and yaw of 3.4 to 8.6 degrees: rows move by up to ~15 px, columns by ~26 px.
  const Eigen::Vector3d omega(0.06, -0.08, 0.15);
  const Eigen::Matrix3d R = rotationFromVector(omega);
  const cv::Mat previous = renderer.render(Eigen::Isometry3d::Identity());
  const cv::Mat current = renderer.render(testing::relativePose(omega, Eigen::Vector3d::Zero()));
  PanoramaWarp warp(c.panorama);
  // Rows near the top and bottom see content outside the previous panorama's field of view.
  const int margin = 20;
  const double right = meanAbsDifference(derotate(warp, current, R), previous, margin);
  const double wrong_sign = meanAbsDifference(derotate(warp, current, R.transpose()), previous, margin);
  const double none = meanAbsDifference(current, previous, margin);
  EXPECT_LT(right, 0.5) << "grey levels";  // 0.17 on 2026-11-25
  EXPECT_GT(wrong_sign, 20 * right);         // 35
  EXPECT_GT(none, 20 * right);               // 31
  // The exact displacement against the calibration's own bearing and projection: the
  // direction of previous pixel (u, v) is R^T b in the current camera, which the current
  // panorama shows at (u + du, v + dv).
  for (double u : {0.0, 300.0, 777.7, 1099.5})
    for (double v : {10.0, 54.5, 100.0}) {
      const Eigen::Vector3d b = R.transpose() * c.panorama.bearing(u, v);
      const double u_cur = c.panorama.column(std::atan2(b.y(), b.x()));
      const double v_cur = c.panorama.row(b.z() / std::hypot(b.x(), b.y()));
      const Eigen::Vector2d d = warp.displacementAt(R, u, v);
      const double W = c.panorama.width;
      EXPECT_NEAR(std::remainder(u + d.x() - u_cur, W), 0.0, 1e-9) << u << ", " << v;
      EXPECT_NEAR(v + d.y(), v_cur, 1e-9) << u << ", " << v;
    }
}

TEST(PanoramaWarp, PureYawIsAWrappedWholePixelColumnShift) {
  Calibration c;
  PanoramaWarp warp(c.panorama);
  const int W = c.panorama.width, H = c.panorama.height;
  const cv::Mat current = randomPanorama(c.panorama);
  // A yaw of exactly 7 columns: du = +-7 everywhere, dv = 0.
  const double yaw = 7 * c.panorama.gamma();
  const Eigen::Matrix3d R = rotationFromVector(Eigen::Vector3d(0.0, 0.0, yaw));
  const Eigen::Vector2d d0 = warp.displacementAt(R, 0.0, 0.0);
  EXPECT_NEAR(std::abs(d0.x()), 7.0, 1e-9);
  for (double u : {0.0, 3.5, 549.0, 1099.0})
    for (double v : {0.0, 54.5, 109.0}) {
      const Eigen::Vector2d d = warp.displacementAt(R, u, v);
      EXPECT_NEAR(d.x(), d0.x(), 1e-9) << u << ", " << v;
      EXPECT_NEAR(d.y(), 0.0, 1e-9) << u << ", " << v;
    }
  // The Keys kernel at whole-pixel offsets is the identity: the output is the input shifted
  // by du columns, across the wrap-around at u = 0 / W.
  const int shift = static_cast<int>(std::lround(d0.x()));
  const cv::Mat out = derotate(warp, current, R);
  double worst = 0.0;
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u)
      worst = std::max(worst, static_cast<double>(std::abs(
                                  out.at<float>(v, u) - current.at<float>(v, ((u + shift) % W + W) % W))));
  EXPECT_LT(worst, 1e-3);
}

TEST(PanoramaWarp, RowsFarBeyondTheEdgesRepeatTheEdgeRows) {
  Calibration c;
  PanoramaWarp warp(c.panorama);
  const int W = c.panorama.width, H = c.panorama.height;
  const cv::Mat current = randomPanorama(c.panorama);
  // A pitch of 0.6 rad moves rows by up to ~105 px: many output pixels sample rows far
  // above or below the panorama (ASan checks that nothing is read outside the padding).
  const Eigen::Matrix3d R = rotationFromVector(Eigen::Vector3d(0.0, 0.6, 0.0));
  const cv::Mat out = derotate(warp, current, R);
  int beyond = 0;
  for (int v = 0; v < H; ++v)
    for (int u = 0; u < W; ++u) {
      const Eigen::Vector2d d = warp.displacementAt(R, u, v);
      const double y = v + d.y();
      if (y > -3.0 && y < H + 2.0) continue;
      ++beyond;
      // All four row taps are the edge row: a 1-D cubic along u of that row, which stays
      // within the kernel's overshoot (Keys a = -0.75: at most 1.5 x the data range).
      const float value = out.at<float>(v, u);
      ASSERT_TRUE(std::isfinite(value)) << u << ", " << v;
      EXPECT_GT(value, -0.25f * 255.0f) << u << ", " << v;
      EXPECT_LT(value, 1.25f * 255.0f) << u << ", " << v;
    }
  EXPECT_GT(beyond, W * H / 10) << "the rotation should reach far beyond the edges";
}

}  // namespace
}  // namespace omnipose
