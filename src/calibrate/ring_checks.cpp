#include "omnipose/calibrate/ring_checks.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <tuple>
#include <opencv2/imgproc.hpp>

#include "common/format.hpp"

namespace omnipose::calibrate {
namespace {

using omnipose::detail::format;


/// Mean over rays (inside the image) and consecutive frame pairs of the squared change, per
/// whole-pixel radius about `c`; NaN where fewer than a quarter of the rays are inside.
std::vector<double> motionProfile(std::span<const cv::Mat> frames, const Eigen::Vector2d& c,
                                  int radii) {
  constexpr int kRays = 720;
  // The sample positions (per radius, the rays inside the image), then the frames one at a
  // time: only the samples of the previous frame are kept.
  std::vector<std::vector<cv::Point>> points(radii);
  const cv::Size size = frames.front().size();
  for (int r = 0; r < radii; ++r) {
    for (int i = 0; i < kRays; ++i) {
      const double a = 2.0 * std::numbers::pi * i / kRays;
      const int x = static_cast<int>(std::lround(c.x() + r * std::cos(a)));
      const int y = static_cast<int>(std::lround(c.y() + r * std::sin(a)));
      if (x < 0 || y < 0 || x >= size.width || y >= size.height) continue;
      points[r].emplace_back(x, y);
    }
  }
  std::vector<double> sum(radii, 0.0);
  std::vector<int> count(radii, 0);
  std::vector<std::vector<float>> prev(radii), cur(radii);
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const cv::Mat grey = toGreyFloat(frames[k]);
    for (int r = 0; r < radii; ++r) {
      cur[r].clear();
      for (const cv::Point& p : points[r]) cur[r].push_back(grey.at<float>(p));
      if (k == 0) continue;
      for (std::size_t j = 0; j < cur[r].size(); ++j) {
        const double d = cur[r][j] - prev[r][j];
        sum[r] += d * d;
        ++count[r];
      }
    }
    std::swap(prev, cur);
  }
  std::vector<double> t(radii);
  for (int r = 0; r < radii; ++r)
    t[r] = count[r] >= static_cast<int>(kRays / 4 * (frames.size() - 1))
               ? sum[r] / count[r]
               : std::numeric_limits<double>::quiet_NaN();
  return t;
}

double quantile(std::vector<double> v, double q) {
  std::erase_if(v, [](double x) { return !std::isfinite(x); });
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto k = static_cast<std::size_t>(q * (v.size() - 1));
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[k];
}

}  // namespace

RingCheck checkRing(std::span<const cv::Mat> frames, const RingEstimate& ring,
                    std::span<const RingDetection> detections, const RingCheckOptions& o) {
  RingCheck out;
  const std::string hint_inner = "try --inner-guess R, more frames of a turning robot, or a "
                                 "lens model (--from-ocamcalib)";
  const std::string hint_outer = "try --outer-guess R, more frames of a turning robot, or a "
                                 "lens model (--from-ocamcalib)";
  // Support: inliers over the rays whose edge point lies inside the image (a ring cut by
  // the image border is not penalised for what the camera cannot see).
  const auto support = [](const RingDetection& d, const RingEdge& e) {
    constexpr int kRays = 720;
    int inside = 0;
    for (int i = 0; i < kRays; ++i) {
      const double a = 2.0 * std::numbers::pi * i / kRays;
      const double x = e.circle.center.x() + e.circle.radius * std::cos(a);
      const double y = e.circle.center.y() + e.circle.radius * std::sin(a);
      inside += x >= 0 && y >= 0 && x <= d.image_size.width - 1 && y <= d.image_size.height - 1;
    }
    return inside > 0 ? e.inlier_fraction * kRays / inside : 0.0;
  };
  for (std::size_t k = 0; k < detections.size(); ++k) {
    const auto& d = detections[k];
    for (const auto& [edge, name, hint] : {std::tuple{&d.inner, "inner", &hint_inner},
                                           std::tuple{&d.outer, "outer", &hint_outer}}) {
      const double f = support(d, *edge);
      if (f < o.min_inlier_fraction)
        out.refusals.push_back(format("frame %.0f: the ", static_cast<double>(k)) + name +
                               format(" edge is supported by only %.0f %% of the rays inside the "
                                      "image (need %.0f %%); ",
                                      100 * f, 100 * o.min_inlier_fraction) +
                               *hint);
    }
  }
  // Agreement.
  if (ring.center_spread > o.max_center_spread || ring.inner_spread > o.max_radius_spread ||
      ring.outer_spread > o.max_radius_spread)
    out.refusals.push_back(format("the frames disagree: centre spread %.2f px, inner %.2f px, outer "
                                  "%.2f px (allowed %.1f / ",
                                  ring.center_spread, ring.inner_spread, ring.outer_spread,
                                  o.max_center_spread) +
                           format("%.1f px); try frames of one lens and mounting, or fix the "
                                  "values with --center/--radius-inner/--radius-outer",
                                  o.max_radius_spread));
  // Motion.
  if (frames.size() < 3) {
    out.notes.push_back("ring not checked against motion (needs 3 or more frames of a moving robot)");
    return out;
  }
  const double r_in = ring.radius_inner, r_out = ring.radius_outer;
  const int radii = static_cast<int>(std::ceil(r_out + o.band_px + 4 * ring.edge_width_outer + 8));
  const std::vector<double> t = motionProfile(frames, ring.center, radii);
  const double noise = quantile(t, 0.1);  // the lens body is still somewhere
  std::vector<double> inside(t.begin() + static_cast<int>(r_in + 5), t.begin() + static_cast<int>(r_out - 5));
  const double ring_motion = quantile(inside, 0.5);
  if (!(ring_motion > 4.0 * noise)) {
    out.notes.push_back(format("ring not checked against motion: the scene hardly moved (change "
                               "%.1f vs noise %.1f grey levels^2)",
                               ring_motion, noise));
    return out;
  }
  const double threshold = o.motion_noise_factor * noise;
  const auto moving = [&](double a, double b) {
    for (int r = std::max(0, static_cast<int>(std::ceil(a))); r <= std::min(radii - 1, static_cast<int>(b)); ++r)
      if (std::isfinite(t[r]) && t[r] > threshold) return r;
    return -1;
  };
  const double gap_in = 3.0 + 2.0 * ring.edge_width_inner, gap_out = 3.0 + 2.0 * ring.edge_width_outer;
  if (const int r = moving(r_out + gap_out, r_out + gap_out + o.band_px); r >= 0)
    out.refusals.push_back(format("the scene moves at radius %d px, beyond the outer edge found at "
                                  "%.1f px: that edge is inside the ring (a scene edge that is a "
                                  "circle, e.g. a horizon); ",
                                  r, r_out) + hint_outer);
  if (const int r = moving(r_in - gap_in - o.band_px, r_in - gap_in); r >= 0)
    out.refusals.push_back(format("the scene moves at radius %d px, inside the inner edge found at "
                                  "%.1f px: that edge is inside the ring (e.g. where a dark floor "
                                  "begins); ",
                                  r, r_in) + hint_inner);
  // Weak edges need motion beside them on the ring's side.
  const double sigma = std::sqrt(std::max(noise, 1e-6) / 2.0);
  double inner_contrast = 0, outer_contrast = 0;
  for (const auto& d : detections) inner_contrast += d.inner.contrast / detections.size();
  for (const auto& d : detections) outer_contrast += d.outer.contrast / detections.size();
  if (inner_contrast < o.weak_edge_sigmas * sigma && moving(r_in + gap_in, r_in + gap_in + o.band_px) < 0)
    out.refusals.push_back(format("the inner edge at %.1f px is weak (step %.1f grey levels, noise "
                                  "%.1f) and nothing moves next to it: it cannot be told from the "
                                  "lens body; ",
                                  r_in, inner_contrast, sigma) + hint_inner);
  if (outer_contrast < o.weak_edge_sigmas * sigma && moving(r_out - gap_out - o.band_px, r_out - gap_out) < 0)
    out.refusals.push_back(format("the outer edge at %.1f px is weak (step %.1f grey levels, noise "
                                  "%.1f) and nothing moves next to it: it cannot be told from the "
                                  "lens body; ",
                                  r_out, outer_contrast, sigma) + hint_outer);
  out.notes.push_back(format("ring checked against motion over %.0f frames: the scene moves inside "
                             "it (change %.1f, noise %.1f grey levels^2) and not beyond its edges",
                             static_cast<double>(frames.size()), ring_motion, noise));
  return out;
}

}  // namespace omnipose::calibrate
