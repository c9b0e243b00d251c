#include "omnipose/calibrate/circle_fit.hpp"

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <span>
#include <utility>

namespace omnipose::calibrate {
namespace {

/// Rings sharing one centre fitted to their points by Gauss-Newton on the orthogonal
/// distances d = |p - c| - r_k: x = (c_x, c_y, r_1, ..., r_K), starting at `x`, at most
/// `max_iterations` steps, each halved until the cost (the sum of d^2) does not grow (at most 20
/// times: the iteration stays monotone). Stops when the cost falls by no more than rounding or
/// the step is negligible. Returns x and its cost; none when the normal equations are singular
/// or a step is not finite.
template <int N>
std::optional<std::pair<Eigen::Matrix<double, N, 1>, double>> fitRings(
    const std::array<std::span<const Eigen::Vector2d>, N - 2>& rings, Eigen::Matrix<double, N, 1> x,
    int max_iterations) {
  using Vec = Eigen::Matrix<double, N, 1>;
  using Mat = Eigen::Matrix<double, N, N>;
  const auto cost = [&](const Vec& v) {
    double s = 0.0;
    for (int k = 0; k < N - 2; ++k) {
      for (const auto& p : rings[k]) s += std::pow((p - v.template head<2>()).norm() - v(2 + k), 2);
    }
    return s;
  };
  double f = cost(x);
  for (int it = 0; it < max_iterations; ++it) {
    // J_i = [-(p_i - c)^T / |p_i - c|, -1 at the ring's radius].
    Mat jtj = Mat::Zero();
    Vec jtd = Vec::Zero();
    for (int k = 0; k < N - 2; ++k) {
      for (const auto& p : rings[k]) {
        const Eigen::Vector2d d = p - x.template head<2>();
        const double rho = d.norm();
        if (rho < 1e-12) continue;
        Vec j = Vec::Zero();
        j(0) = -d.x() / rho;
        j(1) = -d.y() / rho;
        j(2 + k) = -1.0;
        jtj += j * j.transpose();
        jtd += j * (rho - x(2 + k));
      }
    }
    const Eigen::LDLT<Mat> ldlt(jtj);
    if (ldlt.info() != Eigen::Success) return std::nullopt;
    const Vec step = -ldlt.solve(jtd);
    if (!step.allFinite()) return std::nullopt;
    double scale = 1.0;
    bool improved = false;
    for (int h = 0; h < 20; ++h, scale *= 0.5) {
      const Vec trial = x + scale * step;
      const double ft = cost(trial);
      if (ft <= f) {
        x = trial;
        improved = f - ft > 1e-15 * (1.0 + f);
        f = ft;
        break;
      }
    }
    if (!improved || scale * step.norm() < 1e-10) break;
  }
  return std::pair{x, f};
}

double median(std::vector<double> v) {
  if (v.empty()) return 0.0;
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

double rmsDistance(std::span<const Eigen::Vector2d> points, std::span<const int> idx,
                   const Circle& c) {
  if (idx.empty()) return 0.0;
  double s = 0.0;
  for (int i : idx) s += std::pow(c.distance(points[static_cast<std::size_t>(i)]), 2);
  return std::sqrt(s / static_cast<double>(idx.size()));
}

std::vector<Eigen::Vector2d> gather(std::span<const Eigen::Vector2d> points,
                                    std::span<const int> idx) {
  std::vector<Eigen::Vector2d> out;
  out.reserve(idx.size());
  for (int i : idx) out.push_back(points[static_cast<std::size_t>(i)]);
  return out;
}

}  // namespace

std::optional<Circle> fitCircleAlgebraic(std::span<const Eigen::Vector2d> points) {
  const std::size_t n = points.size();
  if (n < 3) return std::nullopt;
  // Centroid-reduced moments (Chernov, "Circular and linear regression", Taubin fit).
  Eigen::Vector2d mean = Eigen::Vector2d::Zero();
  for (const auto& p : points) mean += p;
  mean /= static_cast<double>(n);
  double mxx = 0, myy = 0, mxy = 0, mxz = 0, myz = 0, mzz = 0;
  for (const auto& p : points) {
    const double x = p.x() - mean.x(), y = p.y() - mean.y(), z = x * x + y * y;
    mxx += x * x;
    myy += y * y;
    mxy += x * y;
    mxz += x * z;
    myz += y * z;
    mzz += z * z;
  }
  const double inv = 1.0 / static_cast<double>(n);
  mxx *= inv, myy *= inv, mxy *= inv, mxz *= inv, myz *= inv, mzz *= inv;
  const double mz = mxx + myy;
  const double cov_xy = mxx * myy - mxy * mxy;
  const double var_z = mzz - mz * mz;
  // Characteristic polynomial of Taubin's generalised eigenproblem; Newton from x = 0.
  const double a3 = 4.0 * mz;
  const double a2 = -3.0 * mz * mz - mzz;
  const double a1 = var_z * mz + 4.0 * cov_xy * mz - mxz * mxz - myz * myz;
  const double a0 = mxz * (mxz * myy - myz * mxy) + myz * (myz * mxx - mxz * mxy) - var_z * cov_xy;
  double x = 0.0, y = a0;
  for (int it = 0; it < 99; ++it) {
    const double dy = a1 + x * (2.0 * a2 + 3.0 * a3 * x);
    const double x_new = x - y / dy;
    if (x_new == x || !std::isfinite(x_new)) break;
    const double y_new = a0 + x_new * (a1 + x_new * (a2 + x_new * a3));
    if (std::abs(y_new) >= std::abs(y)) break;
    x = x_new;
    y = y_new;
  }
  const double det = x * x - x * mz + cov_xy;
  if (!(std::abs(det) > 1e-12 * (mz * mz + 1e-300))) return std::nullopt;
  const double cx = (mxz * (myy - x) - myz * mxy) / det / 2.0;
  const double cy = (myz * (mxx - x) - mxz * mxy) / det / 2.0;
  Circle c;
  c.center = mean + Eigen::Vector2d(cx, cy);
  c.radius = std::sqrt(cx * cx + cy * cy + mz);
  if (!std::isfinite(c.radius) || !c.center.allFinite()) return std::nullopt;
  return c;
}

std::optional<Circle> fitCircleGeometric(std::span<const Eigen::Vector2d> points,
                                         const Circle& initial, int max_iterations) {
  if (points.size() < 3) return std::nullopt;
  const Eigen::Vector3d start(initial.center.x(), initial.center.y(), initial.radius);
  const auto fit = fitRings<3>({points}, start, max_iterations);
  if (!fit) return std::nullopt;
  const Eigen::Vector3d& x = fit->first;
  Circle c;
  c.center = x.head<2>();
  c.radius = x(2);
  if (!(c.radius > 0) || !c.center.allFinite()) return std::nullopt;
  return c;
}

std::optional<Circle> circleThrough(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                                    const Eigen::Vector2d& c) {
  // Circumcentre from the perpendicular bisectors, relative to a.
  const Eigen::Vector2d ab = b - a, ac = c - a;
  const double d = 2.0 * (ab.x() * ac.y() - ab.y() * ac.x());
  const double scale = ab.squaredNorm() * ac.squaredNorm();
  if (std::abs(d) < 1e-9 * std::sqrt(scale + 1e-300)) return std::nullopt;
  const double ux = (ac.y() * ab.squaredNorm() - ab.y() * ac.squaredNorm()) / d;
  const double uy = (ab.x() * ac.squaredNorm() - ac.x() * ab.squaredNorm()) / d;
  Circle circle;
  circle.center = a + Eigen::Vector2d(ux, uy);
  circle.radius = std::hypot(ux, uy);
  return circle;
}

std::optional<CircleFit> fitCircleRansac(std::span<const Eigen::Vector2d> points,
                                         const RansacOptions& options) {
  const int n = static_cast<int>(points.size());
  if (n < 3) return std::nullopt;
  const double t = options.inlier_threshold;
  std::mt19937_64 rng(options.seed);
  std::uniform_int_distribution<int> pick(0, n - 1);

  auto acceptable = [&](const Circle& c) {
    if (!(c.radius >= options.min_radius && c.radius <= options.max_radius)) return false;
    if (options.center_prior &&
        (c.center - *options.center_prior).norm() > options.max_center_offset)
      return false;
    return true;
  };

  // MSAC: truncated quadratic cost, so among candidates with similar support the tighter
  // one wins.
  std::optional<Circle> best;
  double best_cost = std::numeric_limits<double>::infinity();
  for (int it = 0; it < options.iterations; ++it) {
    const int i = pick(rng), j = pick(rng), k = pick(rng);
    if (i == j || j == k || i == k) continue;
    const auto c = circleThrough(points[static_cast<std::size_t>(i)],
                                 points[static_cast<std::size_t>(j)],
                                 points[static_cast<std::size_t>(k)]);
    if (!c || !acceptable(*c)) continue;
    double cost = 0.0;
    for (const auto& p : points) cost += std::min(std::pow(c->distance(p), 2), t * t);
    if (cost < best_cost) {
      best_cost = cost;
      best = c;
    }
  }
  if (!best) return std::nullopt;

  // Refinement: inliers -> algebraic (Taubin) -> geometric, re-classified twice with a
  // threshold from the robust spread of the residuals.
  Circle circle = *best;
  double threshold = t;
  std::vector<int> inliers;
  for (int round = 0; round < 3; ++round) {
    inliers.clear();
    for (int i = 0; i < n; ++i)
      if (std::abs(circle.distance(points[static_cast<std::size_t>(i)])) < threshold)
        inliers.push_back(i);
    if (inliers.size() < 3) return std::nullopt;
    const auto pts = gather(points, inliers);
    if (const auto alg = fitCircleAlgebraic(pts); alg && acceptable(*alg)) circle = *alg;
    if (const auto geo = fitCircleGeometric(pts, circle); geo && acceptable(*geo)) circle = *geo;
    std::vector<double> abs_res;
    abs_res.reserve(pts.size());
    for (const auto& p : pts) abs_res.push_back(std::abs(circle.distance(p)));
    const double sigma = 1.4826 * median(abs_res);
    threshold = std::clamp(options.refine_sigmas * sigma, 0.5 * t, 2.0 * t);
  }
  inliers.clear();
  for (int i = 0; i < n; ++i)
    if (std::abs(circle.distance(points[static_cast<std::size_t>(i)])) < threshold)
      inliers.push_back(i);
  if (inliers.size() < 3) return std::nullopt;

  CircleFit fit;
  fit.circle = circle;
  fit.rms = rmsDistance(points, inliers, circle);
  fit.inlier_fraction = static_cast<double>(inliers.size()) / n;
  fit.inliers = std::move(inliers);
  return fit;
}

std::optional<ConcentricFit> fitConcentric(std::span<const Eigen::Vector2d> points1,
                                           std::span<const Eigen::Vector2d> points2,
                                           const ConcentricFit& initial, int max_iterations) {
  if (points1.size() < 3 || points2.size() < 3) return std::nullopt;
  const auto fit = fitRings<4>({points1, points2},
                               Eigen::Vector4d(initial.center.x(), initial.center.y(),
                                               initial.radius1, initial.radius2),
                               max_iterations);
  if (!fit) return std::nullopt;
  const auto& [x, f] = *fit;
  ConcentricFit out;
  out.center = x.head<2>();
  out.radius1 = x(2);
  out.radius2 = x(3);
  out.rms = std::sqrt(f / static_cast<double>(points1.size() + points2.size()));
  if (!x.allFinite() || !(out.radius1 > 0) || !(out.radius2 > 0)) return std::nullopt;
  return out;
}

}  // namespace omnipose::calibrate
