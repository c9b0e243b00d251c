#pragma once
/// \file circle_fit.hpp
/// Circle fits for the lens calibration: algebraic (Taubin), geometric (Gauss-Newton on the
/// orthogonal distances), RANSAC with both refinements, and a concentric fit of two rings
/// that share one centre. Pixel coordinates throughout (x right, y down).

#include <Eigen/Core>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace omnipose::calibrate {

/// A circle in image coordinates, pixels.
struct Circle {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();
  double radius = 0.0;

  /// Signed orthogonal distance of p from the circle: |p - c| - r (positive outside).
  double distance(const Eigen::Vector2d& p) const { return (p - center).norm() - radius; }
};

/// Algebraic fit (Taubin 1991): minimises the algebraic distance of
/// A (x^2 + y^2) + B x + C y + D = 0 under Taubin's gradient normalisation, which removes
/// most of the bias of the Kasa fit on short arcs. Needs >= 3 points not on a line;
/// std::nullopt otherwise.
std::optional<Circle> fitCircleAlgebraic(std::span<const Eigen::Vector2d> points);

/// Geometric fit: Gauss-Newton (with step halving) on sum_i (|p_i - c| - r)^2 from `initial`.
/// Returns std::nullopt when the normal equations are singular or the iteration diverges.
std::optional<Circle> fitCircleGeometric(std::span<const Eigen::Vector2d> points,
                                         const Circle& initial, int max_iterations = 50);

/// The circle through three points; std::nullopt when they are (nearly) collinear.
std::optional<Circle> circleThrough(const Eigen::Vector2d& a, const Eigen::Vector2d& b,
                                    const Eigen::Vector2d& c);

struct RansacOptions {
  int iterations = 600;            ///< random 3-point samples
  double inlier_threshold = 1.5;   ///< |distance| below this is an inlier, pixels
  double min_radius = 1.0;         ///< candidate circles outside [min, max] are skipped
  double max_radius = 1e9;
  /// If set: candidates whose centre is farther than this from `center_prior` are skipped.
  std::optional<Eigen::Vector2d> center_prior;
  double max_center_offset = 1e9;  ///< pixels, with center_prior
  std::uint64_t seed = 1;          ///< the draws are deterministic for a seed
  /// After the refinement, points are re-classified at this many robust sigmas (MAD) of the
  /// inlier residuals, but never tighter than inlier_threshold / 2.
  double refine_sigmas = 3.0;
};

/// Result of a robust circle fit.
struct CircleFit {
  Circle circle;
  std::vector<int> inliers;   ///< indices into the input points
  double rms = 0.0;           ///< RMS orthogonal distance of the inliers, pixels
  double inlier_fraction = 0.0;
};

/// RANSAC on 3-point circles, then algebraic and geometric least squares on the inliers,
/// re-classifying the inliers twice. std::nullopt when fewer than 3 points or no candidate
/// gets 3 inliers.
std::optional<CircleFit> fitCircleRansac(std::span<const Eigen::Vector2d> points,
                                         const RansacOptions& options);

/// Two concentric circles (common centre, radii r1, r2) fitted geometrically to two point
/// sets (Gauss-Newton on the 4 unknowns cx, cy, r1, r2). std::nullopt when either set has
/// fewer than 3 points or the system is singular.
struct ConcentricFit {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();
  double radius1 = 0.0;
  double radius2 = 0.0;
  double rms = 0.0;  ///< RMS orthogonal distance over both sets, pixels
};
std::optional<ConcentricFit> fitConcentric(std::span<const Eigen::Vector2d> points1,
                                           std::span<const Eigen::Vector2d> points2,
                                           const ConcentricFit& initial,
                                           int max_iterations = 50);

}  // namespace omnipose::calibrate
