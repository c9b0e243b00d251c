#include "omnipose/calibrate/ring_detector.hpp"

#include <cstdio>
#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace omnipose::calibrate {
namespace {

constexpr double kPi = std::numbers::pi;

double quantile(std::vector<double> v, double q) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const auto k = static_cast<std::ptrdiff_t>(std::clamp(q, 0.0, 1.0) * (v.size() - 1) + 0.5);
  std::nth_element(v.begin(), v.begin() + k, v.end());
  return v[static_cast<std::size_t>(k)];
}

double median(std::vector<double> v) {
  if (v.empty()) return std::numeric_limits<double>::quiet_NaN();
  const std::size_t n = v.size();
  std::nth_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(n / 2), v.end());
  const double upper = v[n / 2];
  if (n % 2 == 1) return upper;
  return 0.5 * (upper + *std::max_element(v.begin(), v.begin() + static_cast<std::ptrdiff_t>(n / 2)));
}

/// Step 3b: a coherent step beyond the texture interval replaces its boundary when it is
/// this many times stronger than the strongest coherent step about the boundary.
constexpr double kCoherentStepRatio = 1.2;
/// With a step of the same polarity at the boundary, the one beyond must be this much stronger.
constexpr double kSamePolarityStepRatio = 2.5;
/// ... and when the band it crosses has no coherent step of this fraction of its strength.
constexpr double kClearBandRatio = 0.25;

/// The image resampled on rays about a centre: row i = ray at image angle 2 pi i / rays,
/// column k = radius k * step. `valid` marks samples inside the image.
struct Polar {
  cv::Mat p;      ///< CV_32FC1, rays x samples
  cv::Mat valid;  ///< CV_8UC1, 1 where the sample lies inside the image
  int rays = 0;
  double step = 0.5;
  int samples = 0;

  double angle(int i) const { return 2.0 * kPi * i / rays; }
};

Polar samplePolar(const cv::Mat& grey, const Eigen::Vector2d& c, int rays, double step,
                  double r_max) {
  Polar polar;
  polar.rays = rays;
  polar.step = step;
  polar.samples = static_cast<int>(std::floor(r_max / step)) + 1;
  cv::Mat map_x(rays, polar.samples, CV_32FC1), map_y(rays, polar.samples, CV_32FC1);
  polar.valid.create(rays, polar.samples, CV_8UC1);
  const double w1 = grey.cols - 1, h1 = grey.rows - 1;
  for (int i = 0; i < rays; ++i) {
    const double a = polar.angle(i), ca = std::cos(a), sa = std::sin(a);
    auto* mx = map_x.ptr<float>(i);
    auto* my = map_y.ptr<float>(i);
    auto* ok = polar.valid.ptr<std::uint8_t>(i);
    for (int k = 0; k < polar.samples; ++k) {
      const double x = c.x() + k * step * ca, y = c.y() + k * step * sa;
      mx[k] = static_cast<float>(x);
      my[k] = static_cast<float>(y);
      ok[k] = (x >= 0 && x <= w1 && y >= 0 && y <= h1) ? 1 : 0;
    }
  }
  cv::remap(grey, polar.p, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
  return polar;
}

/// Step 3: mean absolute tangential difference over ~3 px of arc, per radius.
std::vector<double> textureProfile(const Polar& polar, const RingDetectorOptions& o) {
  std::vector<double> t(static_cast<std::size_t>(polar.samples),
                        std::numeric_limits<double>::quiet_NaN());
  const int min_count = static_cast<int>(std::ceil(o.min_valid_fraction * polar.rays));
  for (int k = 0; k < polar.samples; ++k) {
    const double r = k * polar.step;
    if (r < o.min_radius) continue;
    const double arc = r * 2.0 * kPi / polar.rays;
    const int kk = std::clamp(static_cast<int>(std::lround(1.5 / arc)), 1, polar.rays / 16);
    double sum = 0.0;
    int count = 0;
    for (int i = 0; i < polar.rays; ++i) {
      const int a = (i + kk) % polar.rays, b = (i - kk + polar.rays) % polar.rays;
      if (!polar.valid.at<std::uint8_t>(a, k) || !polar.valid.at<std::uint8_t>(b, k)) continue;
      sum += std::abs(polar.p.at<float>(a, k) - polar.p.at<float>(b, k));
      ++count;
    }
    if (count >= min_count) t[static_cast<std::size_t>(k)] = sum / count;
  }
  return t;
}

/// The ring's radius interval [r_in, r_out] in pixels from the texture profile: the
/// interval maximising sum (t(r) - tau) (maximum subarray), tau = lo + 0.25 (hi - lo) with lo,
/// hi the 10 % / 90 % quantiles of t. Low-texture parts of the scene (sky, a white wall,
/// paving) are kept when textured radii on both sides outweigh them; the lens body around
/// the ring scores below tau all along. Radii with too few rays inside the image score -tau.
std::optional<std::pair<double, double>> ringInterval(const std::vector<double>& t, double step) {
  // Light smoothing (moving median over ~3 px) against single noisy radii.
  const int n = static_cast<int>(t.size());
  const int half = std::max(1, static_cast<int>(std::lround(1.5 / step)));
  std::vector<double> s(t.size(), std::numeric_limits<double>::quiet_NaN());
  std::vector<double> finite;
  for (int k = 0; k < n; ++k) {
    std::vector<double> w;
    for (int j = std::max(0, k - half); j <= std::min(n - 1, k + half); ++j)
      if (std::isfinite(t[static_cast<std::size_t>(j)])) w.push_back(t[static_cast<std::size_t>(j)]);
    if (std::isfinite(t[static_cast<std::size_t>(k)]) && !w.empty()) {
      s[static_cast<std::size_t>(k)] = median(w);
      finite.push_back(s[static_cast<std::size_t>(k)]);
    }
  }
  if (finite.size() < 10) return std::nullopt;
  const double lo = quantile(finite, 0.1), hi = quantile(finite, 0.9);
  if (!(hi > lo)) return std::nullopt;
  const double tau = lo + 0.25 * (hi - lo);
  // Kadane's maximum subarray on s(r) - tau.
  double best = 0.0, run = 0.0;
  int best_b = -1, best_e = -1, run_b = 0;
  for (int k = 0; k < n; ++k) {
    const double v = s[static_cast<std::size_t>(k)];
    const double score = std::isfinite(v) ? v - tau : -tau;
    if (run <= 0.0) run = 0.0, run_b = k;
    run += score;
    if (run > best) best = run, best_b = run_b, best_e = k;
  }
  if (best_b < 0 || best_e - best_b < 4) return std::nullopt;
  return std::make_pair(best_b * step, best_e * step);
}

/// Radially Gaussian-smoothed polar image (a little angular smoothing too) and its radial
/// derivative dP/dr (central differences), grey levels per pixel.
void radialDerivative(const Polar& polar, double edge_sigma, cv::Mat& smooth, cv::Mat& deriv) {
  cv::GaussianBlur(polar.p, smooth, cv::Size(0, 0), edge_sigma / polar.step, 0.7,
                   cv::BORDER_REPLICATE);
  deriv = cv::Mat::zeros(smooth.size(), CV_32FC1);
  for (int i = 0; i < smooth.rows; ++i) {
    const auto* s = smooth.ptr<float>(i);
    auto* d = deriv.ptr<float>(i);
    for (int k = 1; k + 1 < smooth.cols; ++k)
      d[k] = static_cast<float>((s[k + 1] - s[k - 1]) / (2.0 * polar.step));
  }
}

/// Per-ray edge search of step 4 on the smoothed polar image.
struct EdgeSearch {
  std::vector<Eigen::Vector2d> points;
  std::vector<int> ray_of_point;
  std::vector<double> peak_index;  ///< sub-pixel sample index of each point's edge
  std::vector<double> step_height;
  int polarity = 0;
};

EdgeSearch searchEdges(const Polar& polar, const cv::Mat& deriv, const cv::Mat& smooth,
                       const Eigen::Vector2d& c, double r_lo, double r_hi, int polarity_hint,
                       bool decide_polarity, double edge_sigma) {
  EdgeSearch out;
  const double step = polar.step;
  const int guard = static_cast<int>(std::ceil(4.0 * edge_sigma / step)) + 2;
  const int k_lo = std::max(guard, static_cast<int>(std::floor(r_lo / step)));
  const int k_hi = std::min(polar.samples - 1 - guard, static_cast<int>(std::ceil(r_hi / step)));
  if (k_hi - k_lo < 2) return out;
  const int span = std::max(1, static_cast<int>(std::lround(3.0 / step)));

  struct Peak {
    int ray;
    int k;
    double value;
  };
  auto findPeaks = [&](int polarity) {
    std::vector<Peak> peaks;
    for (int i = 0; i < polar.rays; ++i) {
      const auto* ok = polar.valid.ptr<std::uint8_t>(i);
      bool inside = true;
      for (int k = k_lo - guard; k <= k_hi + guard && inside; ++k) inside = ok[k] != 0;
      if (!inside) continue;
      const auto* d = deriv.ptr<float>(i);
      int best = -1;
      double best_v = 0.0;
      for (int k = k_lo; k <= k_hi; ++k) {
        const double v = polarity == 0 ? std::abs(d[k]) : polarity * d[k];
        if (v > best_v) best_v = v, best = k;
      }
      // A peak on the window border is the flank of an edge outside the window.
      if (best <= k_lo || best >= k_hi) continue;
      peaks.push_back({i, best, best_v});
    }
    return peaks;
  };

  int polarity = polarity_hint;
  std::vector<Peak> peaks = findPeaks(polarity);
  if (decide_polarity && !peaks.empty()) {
    int pos = 0;
    for (const auto& p : peaks) pos += deriv.at<float>(p.ray, p.k) > 0 ? 1 : 0;
    const double frac = static_cast<double>(pos) / static_cast<double>(peaks.size());
    polarity = frac >= 0.7 ? 1 : (frac <= 0.3 ? -1 : 0);
    if (polarity != 0) peaks = findPeaks(polarity);
  }
  out.polarity = polarity;
  if (peaks.empty()) return out;
  // Rays without a real edge there (weak peak) are dropped.
  std::vector<double> values;
  for (const auto& p : peaks) values.push_back(p.value);
  const double min_value = 0.2 * median(values);
  for (const auto& p : peaks) {
    if (p.value < min_value) continue;
    const auto* d = deriv.ptr<float>(p.ray);
    const double sgn = polarity == 0 ? (d[p.k] >= 0 ? 1.0 : -1.0) : polarity;
    const double ym = sgn * d[p.k - 1], y0 = sgn * d[p.k], yp = sgn * d[p.k + 1];
    const double den = ym - 2.0 * y0 + yp;
    const double delta = den < 0 ? std::clamp(0.5 * (ym - yp) / den, -0.5, 0.5) : 0.0;
    const double kf = p.k + delta;
    const double r = kf * step;
    const double a = polar.angle(p.ray);
    out.points.emplace_back(c.x() + r * std::cos(a), c.y() + r * std::sin(a));
    out.ray_of_point.push_back(p.ray);
    out.peak_index.push_back(kf);
    const auto* s = smooth.ptr<float>(p.ray);
    const int kl = std::max(0, p.k - span), kr = std::min(polar.samples - 1, p.k + span);
    out.step_height.push_back(s[kr] - s[kl]);
  }
  return out;
}

/// Edge blur std (pixels) from the mean |dP/dr| profile aligned on each inlier's peak:
/// FWHM / 2.355, the radial smoothing removed in quadrature.
double edgeWidth(const cv::Mat& deriv, const EdgeSearch& search, std::span<const int> inliers,
                 double step, double edge_sigma) {
  const int m = static_cast<int>(std::lround(12.0 / step));
  std::vector<double> acc(static_cast<std::size_t>(2 * m + 1), 0.0);
  std::vector<int> cnt(acc.size(), 0);
  for (int idx : inliers) {
    const int ray = search.ray_of_point[static_cast<std::size_t>(idx)];
    const int k0 = static_cast<int>(std::lround(search.peak_index[static_cast<std::size_t>(idx)]));
    const auto* d = deriv.ptr<float>(ray);
    const double sgn = d[k0] >= 0 ? 1.0 : -1.0;
    for (int j = -m; j <= m; ++j) {
      const int k = k0 + j;
      if (k < 0 || k >= deriv.cols) continue;
      acc[static_cast<std::size_t>(j + m)] += sgn * d[k];
      ++cnt[static_cast<std::size_t>(j + m)];
    }
  }
  for (std::size_t j = 0; j < acc.size(); ++j) acc[j] = cnt[j] ? acc[j] / cnt[j] : 0.0;
  const double peak = acc[static_cast<std::size_t>(m)];
  if (!(peak > 0)) return 0.0;
  auto crossing = [&](int dir) {
    for (int j = 1; j <= m; ++j) {
      const double a = acc[static_cast<std::size_t>(m + dir * (j - 1))];
      const double b = acc[static_cast<std::size_t>(m + dir * j)];
      if (b <= 0.5 * peak) return (j - 1 + (a - 0.5 * peak) / (a - b)) * step;
    }
    return m * step;
  };
  const double sigma_d = (crossing(-1) + crossing(1)) / 2.3548;
  return std::sqrt(std::max(0.0, sigma_d * sigma_d - edge_sigma * edge_sigma));
}

/// 1-D robust radius about a fixed centre: median, then the mean of the points within
/// `threshold` of it, twice.
std::optional<CircleFit> fitRadiusFixedCenter(std::span<const Eigen::Vector2d> pts,
                                              const Eigen::Vector2d& c, double threshold) {
  if (pts.size() < 3) return std::nullopt;
  std::vector<double> r;
  for (const auto& p : pts) r.push_back((p - c).norm());
  double radius = median(r);
  std::vector<int> inliers;
  for (int round = 0; round < 3; ++round) {
    inliers.clear();
    double s = 0.0;
    for (int i = 0; i < static_cast<int>(r.size()); ++i)
      if (std::abs(r[static_cast<std::size_t>(i)] - radius) < threshold)
        inliers.push_back(i), s += r[static_cast<std::size_t>(i)];
    if (inliers.size() < 3) return std::nullopt;
    radius = s / static_cast<double>(inliers.size());
  }
  CircleFit fit;
  fit.circle.center = c;
  fit.circle.radius = radius;
  double ss = 0.0;
  for (int i : inliers) ss += std::pow(r[static_cast<std::size_t>(i)] - radius, 2);
  fit.rms = std::sqrt(ss / static_cast<double>(inliers.size()));
  fit.inlier_fraction = static_cast<double>(inliers.size()) / static_cast<double>(pts.size());
  fit.inliers = std::move(inliers);
  return fit;
}

/// A polar resampling with its smoothed copy and radial derivative.
struct PolarDeriv {
  Polar polar;
  cv::Mat smooth, deriv;
};

PolarDeriv polarDeriv(const cv::Mat& grey, const Eigen::Vector2d& c, const RingDetectorOptions& o,
                      double r_max) {
  PolarDeriv pd;
  pd.polar = samplePolar(grey, c, o.rays, o.radial_step, r_max);
  radialDerivative(pd.polar, o.edge_sigma, pd.smooth, pd.deriv);
  return pd;
}

/// dP/dr of a polar resampling, NaN where the sample lies outside the image: all that
/// step 6 keeps of a frame for M(r).
cv::Mat derivativeInside(const PolarDeriv& pd) {
  cv::Mat d = pd.deriv.clone();
  d.setTo(std::numeric_limits<float>::quiet_NaN(), pd.polar.valid == 0);
  return d;
}

/// Step 6, coherence across rays: M(r) = median over all rays (of all frames) of dP/dr
/// (`derivs` from derivativeInside, one per frame, rays x samples).
/// A lens-body edge has the same sign and place on every ray; scene edges average out.
std::vector<double> medianDerivative(std::span<const cv::Mat> derivs) {
  const int samples = derivs.front().cols;
  std::vector<double> m(static_cast<std::size_t>(samples), 0.0);
  std::vector<double> v;
  for (int k = 0; k < samples; ++k) {
    v.clear();
    for (const cv::Mat& d : derivs)
      for (int i = 0; i < d.rows; ++i)
        if (const float x = d.at<float>(i, k); !std::isnan(x)) v.push_back(x);
    m[static_cast<std::size_t>(k)] = v.size() >= 16 ? median(v) : 0.0;
  }
  return m;
}

/// The next stacked edge beyond r_edge in direction dir (+1 outward, -1 inward), not past
/// `limit`: the strongest local extreme of |M| in the band, if at least stack_min_contrast
/// of |M| at the first edge r_first. Sub-sample radius by a parabola.
std::optional<double> nextStacked(const std::vector<double>& m, double step, double r_edge,
                                  double r_first, double width, int dir, double limit,
                                  const RingDetectorOptions& o) {
  const int n = static_cast<int>(m.size());
  auto at = [&](int k) { return k >= 0 && k < n ? std::abs(m[static_cast<std::size_t>(k)]) : 0.0; };
  // Strength reference: the first (strongest) edge, so weak steps cannot chain.
  const int ke = static_cast<int>(std::lround(r_first / step));
  double own = 0.0;
  for (int k = ke - static_cast<int>(2.0 / step); k <= ke + static_cast<int>(2.0 / step); ++k)
    own = std::max(own, at(k));
  if (!(own > 0)) return std::nullopt;
  // Skip the edge's own derivative lobe, then a band of a fraction of the radius.
  const double gap = std::max(2.0, 2.5 * std::hypot(width, o.edge_sigma));
  const double band = std::max(6.0, o.stack_band_fraction * r_edge);
  double lo = dir > 0 ? r_edge + gap : r_edge - gap - band;
  double hi = dir > 0 ? r_edge + gap + band : r_edge - gap;
  if (dir > 0) hi = std::min(hi, limit);
  else lo = std::max(lo, limit);
  const int k_lo = std::max(1, static_cast<int>(std::ceil(lo / step)));
  const int k_hi = std::min(n - 2, static_cast<int>(std::floor(hi / step)));
  int best = -1;
  for (int k = k_lo; k <= k_hi; ++k)
    if (at(k) >= at(k - 1) && at(k) >= at(k + 1) && (best < 0 || at(k) > at(best))) best = k;
  if (best < 0 || at(best) < o.stack_min_contrast * own) return std::nullopt;
  const double ym = at(best - 1), y0 = at(best), yp = at(best + 1);
  const double den = ym - 2.0 * y0 + yp;
  const double delta = den < 0 ? std::clamp(0.5 * (ym - yp) / den, -0.5, 0.5) : 0.0;
  return (best + delta) * step;
}

/// The per-ray edge points of one frame within +-tol of radius rr (polarity of M there),
/// fitted about the fixed centre; `edge` is replaced on success.
bool edgeNear(const PolarDeriv& pd, const Eigen::Vector2d& c, double rr, int polarity,
              const RingDetectorOptions& o, RingEdge& edge) {
  const double tol = std::max(2.0, 2.0 * o.inlier_threshold);
  const EdgeSearch s =
      searchEdges(pd.polar, pd.deriv, pd.smooth, c, rr - tol, rr + tol, polarity, false, o.edge_sigma);
  const auto fit = fitRadiusFixedCenter(s.points, c, o.inlier_threshold);
  if (!fit) return false;
  edge.circle = fit->circle;
  edge.points = s.points;
  edge.inliers = fit->inliers;
  edge.rms = fit->rms;
  edge.inlier_fraction = static_cast<double>(fit->inliers.size()) / o.rays;
  edge.polarity = polarity;
  edge.width = edgeWidth(pd.deriv, s, fit->inliers, o.radial_step, o.edge_sigma);
  std::vector<double> h;
  for (int i : fit->inliers) h.push_back(std::abs(s.step_height[static_cast<std::size_t>(i)]));
  edge.contrast = median(h);
  return true;
}

/// Step 6 on one or more frames of the same lens (pooled M), about the common centre c.
/// Moves r_in outward / r_out inward past stacked lens-body edges and updates each
/// detection's edge to the per-ray points of its own frame there. `frames[f]` is the image
/// of `dets[f]`. Memory per frame: its radial derivative only (for M); a frame's full polar
/// resampling is made again when its edge is searched.
void applyStacked(std::span<const cv::Mat* const> frames, std::span<RingDetection*> dets,
                  const Eigen::Vector2d& c, double& r_in, double& r_out,
                  const RingDetectorOptions& o) {
  auto greyOf = [](const cv::Mat& frame) {
    return frame.type() == CV_32FC1 ? frame : toGreyFloat(frame);
  };
  std::vector<double> r_max;  // per frame, fixed before r_out moves
  std::vector<cv::Mat> derivs;
  r_max.reserve(frames.size());
  derivs.reserve(frames.size());
  for (const cv::Mat* frame : frames) {
    const double w1 = frame->cols - 1, h1 = frame->rows - 1;
    const double corner = std::max({c.norm(), (c - Eigen::Vector2d(w1, 0)).norm(),
                                    (c - Eigen::Vector2d(0, h1)).norm(),
                                    (c - Eigen::Vector2d(w1, h1)).norm()});
    r_max.push_back(std::min(corner, r_out + 20.0));
    derivs.push_back(derivativeInside(polarDeriv(greyOf(*frame), c, o, r_max.back())));
  }
  const std::vector<double> m = medianDerivative(derivs);
  for (int dir : {+1, -1}) {
    double& radius = dir > 0 ? r_in : r_out;
    const double first = radius;
    for (int step = 0; step < 3; ++step) {
      double width = 0.0;
      for (auto* d : dets) width = std::max(width, (dir > 0 ? d->inner : d->outer).width);
      const auto next = nextStacked(m, o.radial_step, radius, first, width, dir,
                                    0.5 * (r_in + r_out), o);
      if (!next) break;
      const double mk = m[static_cast<std::size_t>(std::lround(*next / o.radial_step))];
      const int polarity = mk >= 0 ? 1 : -1;
      bool all = true;
      std::vector<RingEdge> updated;
      for (std::size_t f = 0; f < dets.size() && all; ++f) {
        RingEdge e = dir > 0 ? dets[f]->inner : dets[f]->outer;
        const PolarDeriv pd = polarDeriv(greyOf(*frames[f]), c, o, r_max[f]);
        all = edgeNear(pd, c, *next, polarity, o, e);
        updated.push_back(std::move(e));
      }
      if (!all) break;
      // The pooled radius: inlier-count weighted mean of the frames' fits.
      double sw = 0.0, sr = 0.0;
      for (const auto& e : updated) {
        sw += static_cast<double>(e.inliers.size());
        sr += static_cast<double>(e.inliers.size()) * e.circle.radius;
      }
      radius = sr / sw;
      for (std::size_t f = 0; f < dets.size(); ++f) {
        RingEdge& e = dir > 0 ? dets[f]->inner : dets[f]->outer;
        const double first = e.first_radius;
        const int stacked = e.stacked;
        e = std::move(updated[f]);
        e.first_radius = first;
        e.stacked = stacked + 1;
        (dir > 0 ? dets[f]->radius_inner : dets[f]->radius_outer) = e.circle.radius;
      }
    }
  }
}

}  // namespace

std::vector<std::string> RingDetectorOptions::validate() const {
  std::vector<std::string> p;
  if (rays < 64) p.push_back("rays: must be >= 64");
  if (!(radial_step > 0 && radial_step <= 2)) p.push_back("radial_step: must be in (0, 2] px");
  if (!(edge_sigma > 0 && edge_sigma <= 10)) p.push_back("edge_sigma: must be in (0, 10] px");
  if (vote_size < 64) p.push_back("vote_size: must be >= 64");
  if (!(min_radius >= 0)) p.push_back("min_radius: must be >= 0");
  if (max_radius && !(*max_radius > min_radius)) p.push_back("max_radius: must be > min_radius");
  if (inner_guess && outer_guess && !(*outer_guess > *inner_guess))
    p.push_back("outer_guess: must be greater than inner_guess");
  if (!(search_fraction > 0 && search_fraction < 0.5))
    p.push_back("search_fraction: must be in (0, 0.5)");
  if (!(min_valid_fraction > 0 && min_valid_fraction <= 1))
    p.push_back("min_valid_fraction: must be in (0, 1]");
  if (passes < 1) p.push_back("passes: must be >= 1");
  if (!(inlier_threshold > 0)) p.push_back("inlier_threshold: must be > 0");
  return p;
}

cv::Mat toGreyFloat(const cv::Mat& image) {
  cv::Mat grey;
  if (image.channels() == 3) cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  else if (image.channels() == 4) cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY);
  else grey = image;
  cv::Mat out;
  if (grey.depth() == CV_8U) grey.convertTo(out, CV_32F);
  else if (grey.depth() == CV_16U) grey.convertTo(out, CV_32F, 255.0 / 65535.0);
  else grey.convertTo(out, CV_32F);
  return out;
}

Eigen::Vector2d voteCenter(const cv::Mat& grey, int vote_size) {
  const double s = std::max(1.0, static_cast<double>(std::max(grey.cols, grey.rows)) / vote_size);
  cv::Mat small;
  if (s > 1.0)
    cv::resize(grey, small,
               cv::Size(static_cast<int>(std::lround(grey.cols / s)),
                        static_cast<int>(std::lround(grey.rows / s))),
               0, 0, cv::INTER_AREA);
  else
    small = grey.clone();
  const double sx = static_cast<double>(grey.cols) / small.cols;
  const double sy = static_cast<double>(grey.rows) / small.rows;
  cv::GaussianBlur(small, small, cv::Size(0, 0), 1.5);
  cv::Mat gx, gy;
  cv::Sobel(small, gx, CV_32F, 1, 0, 3);
  cv::Sobel(small, gy, CV_32F, 0, 1, 3);
  cv::Mat mag;
  cv::magnitude(gx, gy, mag);
  std::vector<double> m;
  m.reserve(mag.total());
  for (int y = 0; y < mag.rows; ++y)
    for (int x = 0; x < mag.cols; ++x) m.push_back(mag.at<float>(y, x));
  const double threshold = std::max(1e-3, quantile(m, 0.85));
  const double cap = std::max(threshold, quantile(m, 0.99));

  // Hough-style voting along both directions of each strong gradient.
  cv::Mat acc = cv::Mat::zeros(small.size(), CV_32FC1);
  const double r_max = 0.75 * std::max(small.cols, small.rows);
  for (int y = 0; y < small.rows; ++y) {
    for (int x = 0; x < small.cols; ++x) {
      const double g = mag.at<float>(y, x);
      if (g < threshold) continue;
      const double dx = gx.at<float>(y, x) / g, dy = gy.at<float>(y, x) / g;
      const float w = static_cast<float>(std::min(g, cap) / cap);
      for (int sign = -1; sign <= 1; sign += 2) {
        for (double r = 3.0; r < r_max; r += 1.0) {
          const int px = static_cast<int>(std::lround(x + sign * r * dx));
          const int py = static_cast<int>(std::lround(y + sign * r * dy));
          if (px < 0 || py < 0 || px >= small.cols || py >= small.rows) break;
          acc.at<float>(py, px) += w;
        }
      }
    }
  }
  cv::GaussianBlur(acc, acc, cv::Size(0, 0), 2.0);
  cv::Point best;
  cv::minMaxLoc(acc, nullptr, nullptr, nullptr, &best);
  // Sub-cell peak: parabola per axis.
  auto sub = [&](int dxs, int dys) {
    const int x0 = best.x, y0 = best.y;
    if (x0 - dxs < 0 || y0 - dys < 0 || x0 + dxs >= acc.cols || y0 + dys >= acc.rows) return 0.0;
    const double a = acc.at<float>(y0 - dys, x0 - dxs), b = acc.at<float>(y0, x0),
                 c = acc.at<float>(y0 + dys, x0 + dxs);
    const double den = a - 2 * b + c;
    return den < 0 ? std::clamp(0.5 * (a - c) / den, -0.5, 0.5) : 0.0;
  };
  const double bx = best.x + sub(1, 0), by = best.y + sub(0, 1);
  return {(bx + 0.5) * sx - 0.5, (by + 0.5) * sy - 0.5};
}

namespace {

/// Step 3b: a textureless band of the scene at a ring edge (ceiling, sky, floor) ends
/// the texture interval inside the ring. The ring's edges are the strongest steps that
/// are coherent over all rays (a lens-body edge is a circle; scene edges average out in
/// the median): where a clearly stronger one lies beyond the texture interval, the
/// boundary moves onto it.
/// `w_in` and `w_out` are the search windows about r_in and r_out.
void moveToCoherentSteps(const Polar& polar, const RingDetectorOptions& o, double w_in,
                         double w_out, double& r_in, double& r_out, RingDetection& det) {
  cv::Mat smooth0, deriv0;
  radialDerivative(polar, o.edge_sigma, smooth0, deriv0);
  PolarDeriv pd{polar, smooth0, deriv0};
  const cv::Mat inside = derivativeInside(pd);
  const std::vector<double> m = medianDerivative(std::span<const cv::Mat>(&inside, 1));
  struct Step {
    double strength = 0.0;  ///< |M|
    double radius = 0.0;
    int sign = 0;           ///< +1: brighter outward
  };
  const auto strongest = [&](double a, double b) {
    Step best;
    for (int k = std::max(0, static_cast<int>(a / o.radial_step));
         k <= std::min(static_cast<int>(m.size()) - 1, static_cast<int>(b / o.radial_step)); ++k) {
      const double v = m[static_cast<std::size_t>(k)];
      if (std::abs(v) > best.strength) best = {std::abs(v), k * o.radial_step, v > 0 ? 1 : -1};
    }
    return best;
  };
  const double last = (static_cast<int>(m.size()) - 3) * o.radial_step;
  // Only across a band free of other coherent steps: a lens body beyond the ring
  // (bezels, housings) is a stack of concentric steps, a textureless scene band is not.
  const auto clearBand = [&](double a, double b, double strength) {
    return strongest(a, b).strength < kClearBandRatio * strength;
  };
  // A step of the other polarity at the texture boundary is a scene edge (a horizon
  // under a bright sky); one of the same polarity may be the ring's own edge in front
  // of a brighter bezel, so then the step beyond must be much stronger.
  const auto moves = [&](const Step& here, const Step& there) {
    const double ratio = there.strength / std::max(here.strength, 1e-9);
    return ratio > (here.sign != there.sign ? kCoherentStepRatio : kSamePolarityStepRatio);
  };
  const double lobe = 2.0 + 3.0 * o.edge_sigma;  // an edge's own derivative lobe
  if (!o.outer_guess) {
    const auto here = strongest(r_out - w_out, r_out + w_out);
    const auto beyond = strongest(r_out + w_out, last);
    if (moves(here, beyond) && clearBand(r_out + w_out, beyond.radius - lobe, beyond.strength)) {
      r_out = beyond.radius;
      det.outer_moved_to_step = true;
    }
  }
  if (!o.inner_guess) {
    const auto here = strongest(r_in - w_in, r_in + w_in);
    const auto before = strongest(o.min_radius, r_in - w_in);
    if (moves(here, before) && clearBand(before.radius + lobe, r_in - w_in, before.strength)) {
      r_in = before.radius;
      det.inner_moved_to_step = true;
    }
  }
}

/// Both rings share the mirror axis: the concentric geometric fit on the two circles'
/// inliers (about the fixed centre `c`, only the radii, when `fixed_center`).
std::optional<ConcentricFit> concentricFit(const EdgeSearch& inner, const EdgeSearch& outer,
                                           const CircleFit& fit_in, const CircleFit& fit_out,
                                           const Eigen::Vector2d& c, bool fixed_center) {
  std::vector<Eigen::Vector2d> pin, pout;
  for (int i : fit_in.inliers) pin.push_back(inner.points[static_cast<std::size_t>(i)]);
  for (int i : fit_out.inliers) pout.push_back(outer.points[static_cast<std::size_t>(i)]);
  if (!fixed_center) {
    ConcentricFit init;
    init.center = 0.5 * (fit_in.circle.center + fit_out.circle.center);
    init.radius1 = fit_in.circle.radius;
    init.radius2 = fit_out.circle.radius;
    return fitConcentric(pin, pout, init);
  }
  ConcentricFit cf;
  cf.center = c;
  cf.radius1 = fit_in.circle.radius;
  cf.radius2 = fit_out.circle.radius;
  double ss = 0.0;
  for (const auto& p : pin) ss += std::pow((p - c).norm() - cf.radius1, 2);
  for (const auto& p : pout) ss += std::pow((p - c).norm() - cf.radius2, 2);
  cf.rms = std::sqrt(ss / static_cast<double>(pin.size() + pout.size()));
  return cf;
}

/// An edge's result: its circle, points and inliers, width, polarity and contrast.
void fillEdge(RingEdge& e, const EdgeSearch& s, const CircleFit& f, const cv::Mat& deriv,
              const RingDetectorOptions& o) {
  e.circle = f.circle;
  e.points = s.points;
  e.inliers = f.inliers;
  e.rms = f.rms;
  e.inlier_fraction = static_cast<double>(f.inliers.size()) / o.rays;
  e.polarity = s.polarity;
  e.width = edgeWidth(deriv, s, f.inliers, o.radial_step, o.edge_sigma);
  std::vector<double> h;
  for (int i : f.inliers) h.push_back(std::abs(s.step_height[static_cast<std::size_t>(i)]));
  e.contrast = median(h);
}

}  // namespace

namespace {

/// Step 2: the polar image about `c`, out to the farthest image corner (or o.max_radius).
Polar polarAbout(const cv::Mat& grey, const Eigen::Vector2d& c, const RingDetectorOptions& o) {
  const double corner = std::max({(c - Eigen::Vector2d(0, 0)).norm(),
                                  (c - Eigen::Vector2d(grey.cols - 1, 0)).norm(),
                                  (c - Eigen::Vector2d(0, grey.rows - 1)).norm(),
                                  (c - Eigen::Vector2d(grey.cols - 1, grey.rows - 1)).norm()});
  const double r_max = o.max_radius ? std::min(*o.max_radius, corner) : corner;
  return samplePolar(grey, c, o.rays, o.radial_step, r_max);
}

/// Step 3 (the first pass): the coarse ring radii r_in, r_out and their search windows
/// w_in, w_out (not overlapping), from the texture profile and the coherent steps.
Expected<void> coarseRing(const Polar& polar, const RingDetectorOptions& o,
                          const Eigen::Vector2d& c, RingDetection& det, double& r_in,
                          double& r_out, double& w_in, double& w_out) {
  // Step 3: coarse ring from the tangential texture profile.
  det.texture_profile = textureProfile(polar, o);
  const auto interval = ringInterval(det.texture_profile, o.radial_step);
  if (!interval && !(o.inner_guess && o.outer_guess))
    return fail(ErrorCode::kIllConditioned,
                "ring detector: no textured ring found about (%.1f, %.1f)", c.x(), c.y());
  r_in = o.inner_guess ? *o.inner_guess : interval->first;
  r_out = o.outer_guess ? *o.outer_guess : interval->second;
  w_in = std::max(6.0, o.search_fraction * r_in);
  w_out = std::max(6.0, o.search_fraction * r_out);
  // Step 3b: edges moved onto the ring's coherent steps.
  moveToCoherentSteps(polar, o, w_in, w_out, r_in, r_out, det);
  w_in = std::max(6.0, o.search_fraction * r_in);
  w_out = std::max(6.0, o.search_fraction * r_out);
  det.coarse_inner = r_in;
  det.coarse_outer = r_out;
  // The two windows must not overlap: split at the middle.
  const double mid = 0.5 * (r_in + r_out);
  w_in = std::min(w_in, mid - r_in - 1.0);
  w_out = std::min(w_out, r_out - mid - 1.0);
  if (w_in < 2.0 || w_out < 2.0)
    return fail(ErrorCode::kIllConditioned, "ring detector: ring too narrow (%.1f..%.1f px)",
                r_in, r_out);
  return {};
}

}  // namespace

Expected<RingDetection> detectRing(const cv::Mat& image, const RingDetectorOptions& o) {
  if (const auto problems = o.validate(); !problems.empty())
    return fail(ErrorCode::kInvalidArgument, "ring detector: %s", problems.front().c_str());
  if (image.empty()) return fail(ErrorCode::kInvalidArgument, "ring detector: empty image");
  const cv::Mat grey = toGreyFloat(image);

  RingDetection det;
  det.image_size = grey.size();
  det.radial_step = o.radial_step;
  det.coarse_center = o.fixed_center   ? *o.fixed_center
                      : o.center_guess ? *o.center_guess
                                       : voteCenter(grey, o.vote_size);
  Eigen::Vector2d c = det.coarse_center;

  double r_in = 0.0, r_out = 0.0, w_in = 0.0, w_out = 0.0;
  int pol_in = 0, pol_out = 0;
  for (int pass = 0; pass < o.passes; ++pass) {
    // Step 2: polar resampling about the current centre.
    const Polar polar = polarAbout(grey, c, o);

    if (pass == 0) {
      if (auto coarse = coarseRing(polar, o, c, det, r_in, r_out, w_in, w_out); !coarse)
        return std::unexpected(coarse.error());
    }

    // Step 4: radial derivative of the smoothed polar image (a little angular smoothing too).
    cv::Mat smooth, deriv;
    radialDerivative(polar, o.edge_sigma, smooth, deriv);
    const EdgeSearch inner = searchEdges(polar, deriv, smooth, c, r_in - w_in, r_in + w_in,
                                         pol_in, pass == 0, o.edge_sigma);
    const EdgeSearch outer = searchEdges(polar, deriv, smooth, c, r_out - w_out, r_out + w_out,
                                         pol_out, pass == 0, o.edge_sigma);
    if (pass == 0) pol_in = inner.polarity, pol_out = outer.polarity;

    // Step 5: a robust circle per boundary.
    auto fitEdge = [&](const EdgeSearch& s, double r0, double w) -> std::optional<CircleFit> {
      if (o.fixed_center) return fitRadiusFixedCenter(s.points, c, o.inlier_threshold);
      RansacOptions ro;
      ro.inlier_threshold = o.inlier_threshold;
      ro.min_radius = std::max(1.0, r0 - w - 2.0);
      ro.max_radius = r0 + w + 2.0;
      ro.center_prior = c;
      ro.max_center_offset = std::max(10.0, w);
      ro.seed = o.seed + static_cast<std::uint64_t>(pass);
      return fitCircleRansac(s.points, ro);
    };
    const auto fit_in = fitEdge(inner, r_in, w_in);
    const auto fit_out = fitEdge(outer, r_out, w_out);
    if (!fit_in || !fit_out)
      return fail(ErrorCode::kIllConditioned,
                  "ring detector: no circle fits the %s edge (%zu edge points about r = %.1f px)",
                  !fit_in ? "inner" : "outer", !fit_in ? inner.points.size() : outer.points.size(),
                  !fit_in ? r_in : r_out);

    const std::optional<ConcentricFit> fitted =
        concentricFit(inner, outer, *fit_in, *fit_out, c, o.fixed_center.has_value());
    if (!fitted) return fail(ErrorCode::kIllConditioned, "ring detector: concentric fit failed");
    const ConcentricFit& cf = *fitted;

    fillEdge(det.inner, inner, *fit_in, deriv, o);
    fillEdge(det.outer, outer, *fit_out, deriv, o);
    det.center = cf.center;
    det.radius_inner = cf.radius1;
    det.radius_outer = cf.radius2;
    det.rms = cf.rms;

    // Next pass: re-centre and search narrowly about the fitted radii.
    c = cf.center;
    r_in = cf.radius1;
    r_out = cf.radius2;
    w_in = std::max(4.0, 4.0 * det.inner.rms + 2.0 * det.inner.width);
    w_out = std::max(4.0, 4.0 * det.outer.rms + 2.0 * det.outer.width);
    const double mid = 0.5 * (r_in + r_out);
    w_in = std::min(w_in, mid - r_in - 1.0);
    w_out = std::min(w_out, r_out - mid - 1.0);
  }
  // Step 6: stacked edges, about the final centre.
  det.inner.first_radius = det.radius_inner;
  det.outer.first_radius = det.radius_outer;
  if (o.stacked_edges) {
    RingDetection* d = &det;
    const cv::Mat* g = &grey;
    applyStacked(std::span<const cv::Mat* const>(&g, 1), std::span<RingDetection*>(&d, 1), det.center,
                 det.radius_inner, det.radius_outer, o);
  }
  return det;
}

RingEstimate combineDetections(std::span<const RingDetection> detections) {
  if (detections.empty()) throw std::invalid_argument("combineDetections: no detections");
  std::vector<double> cx, cy, ri, ro, wi, wo, fi, fo;
  for (const auto& d : detections) {
    cx.push_back(d.center.x());
    cy.push_back(d.center.y());
    ri.push_back(d.radius_inner);
    ro.push_back(d.radius_outer);
    wi.push_back(d.inner.width);
    wo.push_back(d.outer.width);
    fi.push_back(d.inner.first_radius);
    fo.push_back(d.outer.first_radius);
  }
  RingEstimate e;
  e.frames = static_cast<int>(detections.size());
  e.center = {median(cx), median(cy)};
  e.radius_inner = median(ri);
  e.radius_outer = median(ro);
  e.edge_width_inner = median(wi);
  e.edge_width_outer = median(wo);
  e.first_inner = median(fi);
  e.first_outer = median(fo);
  e.stacked_inner = detections.front().inner.stacked;
  e.stacked_outer = detections.front().outer.stacked;
  for (const auto& d : detections) {
    e.center_spread = std::max(e.center_spread, (d.center - e.center).norm());
    e.inner_spread = std::max(e.inner_spread, std::abs(d.radius_inner - e.radius_inner));
    e.outer_spread = std::max(e.outer_spread, std::abs(d.radius_outer - e.radius_outer));
  }
  return e;
}

}  // namespace omnipose::calibrate

namespace omnipose::calibrate {

MultiRingDetection detectRings(std::span<const cv::Mat> frames, const RingDetectorOptions& o) {
  MultiRingDetection out;
  RingDetectorOptions per_frame = o;
  per_frame.stacked_edges = false;
  std::vector<const cv::Mat*> detected;  // the frames of out.detections
  for (const auto& f : frames) {
    auto d = detectRing(f, per_frame);
    if (d) {
      out.detections.push_back(std::move(*d));
      detected.push_back(&f);
      out.errors.emplace_back();
    } else {
      out.errors.emplace_back(d.error().message());
    }
  }
  if (out.detections.empty()) return out;
  RingEstimate e = combineDetections(out.detections);
  if (o.stacked_edges) {
    std::vector<RingDetection*> dets;
    for (auto& d : out.detections) dets.push_back(&d);
    double r_in = e.radius_inner, r_out = e.radius_outer;
    applyStacked(detected, dets, e.center, r_in, r_out, o);
    e = combineDetections(out.detections);
    e.radius_inner = r_in;
    e.radius_outer = r_out;
  }
  out.estimate = e;
  return out;
}

}  // namespace omnipose::calibrate
