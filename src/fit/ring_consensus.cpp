#include "omnipose/ring_consensus.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <numbers>

#include <Eigen/Dense>

namespace omnipose {
namespace {

constexpr double kMadToSigma = 1.4826;
constexpr int kMinSamples = 8;
/// inconsistent[] while it is built: flagged by the threshold, or beside such a window.
constexpr std::uint8_t kFlagged = 1, kBesideFlagged = 2;
/// Two samples are neighbours when their azimuths are within this many mean spacings.
constexpr double kNeighbourSpacings = 1.6;
/// Triples whose 3 x 3 system has a smaller determinant are skipped (an equilateral triple
/// of azimuths has 3 sqrt(3) / 2 = 2.6; three windows within 20 degrees about 0.03).
constexpr double kMinDeterminant = 0.2;
/// Alternations of depths and sinusoid in the consensus's refit.
constexpr int kDepthIterations = 10;

bool hasConfidence(const RingSample& q) { return std::isfinite(q.confidence) && q.confidence > 0; }

/// The sinusoid p0 + p1 sin theta + p2 cos theta.
using Sinusoid = Eigen::Vector3d;

/// Each sample's sin theta and cos theta, computed once per call.
struct Azimuths {
  std::span<const double> sin, cos;

  Eigen::RowVector3d basis(int q) const { return Eigen::RowVector3d(1.0, sin[q], cos[q]); }
  /// The translation's part of du at sample q under p, for unit inverse depth.
  double moving(int q, const Sinusoid& p) const { return p(1) * sin[q] + p(2) * cos[q]; }
};

double medianOf(std::span<double> values) {
  const auto mid = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), mid, values.end());
  return *mid;
}

/// du = a + lambda (b sin theta + c cos theta): the yaw a, the translation's harmonic (b, c)
/// times the window's relative inverse depth lambda.
struct DuModel {
  double max_inverse_depth;
  Azimuths azimuths;

  Eigen::RowVector3d row(int q, double lambda) const {
    return Eigen::RowVector3d(1.0, lambda * azimuths.sin[q], lambda * azimuths.cos[q]);
  }
  /// The relative inverse depth in [0, max] that fits sample q (du du_px) best under p.
  double bestDepth(int q, double du_px, const Sinusoid& p) const {
    const double moving = azimuths.moving(q, p);
    if (!(std::abs(moving) > 1e-12)) return 1.0;
    return std::clamp((du_px - p(0)) / moving, 0.0, max_inverse_depth);
  }
  /// |du - model| at that depth.
  double absorbedResidual(int q, double du_px, const Sinusoid& p) const {
    return std::abs(du_px - p(0) - bestDepth(q, du_px, p) * azimuths.moving(q, p));
  }
};

/// Least median of absolute residuals of the model with one depth for every window, over
/// triples of samples spread around the ring (index spacings of a third, a quarter and a
/// sixth of the ring); then, on the samples within 2.5 robust sigmas of it, alternately each
/// one's depth and the sinusoid by least squares (mean depth 1 over them), so that walls at
/// different distances do not turn the consensus's translation. Returns false when no triple
/// is well conditioned. `work`: samples.size() values, the last depths on return;
/// `one_depth_sigma`: the robust sigma of the least-median fit's residuals (one depth for
/// every window), pixels.
bool consensusSinusoid(std::span<const RingSample> s, const DuModel& model,
                       std::span<double> work, Sinusoid& best, double& one_depth_sigma) {
  const int m = static_cast<int>(s.size());
  const std::array<std::array<int, 2>, 3> spacing{
      {{m / 3, 2 * m / 3}, {m / 4, m / 2}, {m / 6, m / 2}}};
  double best_score = INFINITY;
  for (const auto& [d1, d2] : spacing) {
    for (int i = 0; i < m; ++i) {
      const int j = (i + d1) % m, k = (i + d2) % m;
      Eigen::Matrix3d A;
      A << model.azimuths.basis(i), model.azimuths.basis(j), model.azimuths.basis(k);
      if (!(std::abs(A.determinant()) > kMinDeterminant)) continue;
      const Sinusoid p = A.partialPivLu().solve(
          Eigen::Vector3d(s[i].du_px, s[j].du_px, s[k].du_px));
      for (int q = 0; q < m; ++q) work[q] = std::abs(s[q].du_px - model.azimuths.basis(q).dot(p));
      const double score = medianOf(work.first(m));
      if (score < best_score) {
        best_score = score;
        best = p;
      }
    }
  }
  if (!std::isfinite(best_score)) return false;
  // Rousseeuw's small-sample correction for three parameters.
  const double sigma = kMadToSigma * (1.0 + 5.0 / std::max(m - 3, 1)) * best_score;
  one_depth_sigma = sigma;
  const double gate = std::max(2.5 * sigma, 1e-6);
  // work[q]: the sample's depth, negative for the samples outside the gate.
  for (int q = 0; q < m; ++q)
    work[q] = std::abs(s[q].du_px - model.azimuths.basis(q).dot(best)) < gate ? 1.0 : -1.0;
  for (int iteration = 0; iteration < kDepthIterations; ++iteration) {
    Eigen::Matrix3d N = Eigen::Matrix3d::Zero();
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    int used = 0;
    for (int q = 0; q < m; ++q) {
      if (work[q] < 0) continue;
      const Eigen::RowVector3d a = model.row(q, work[q]);
      N.noalias() += a.transpose() * a;
      g.noalias() += a.transpose() * s[q].du_px;
      ++used;
    }
    if (used < 3) break;
    const Eigen::LDLT<Eigen::Matrix3d> ldlt(N);
    const Sinusoid refit = ldlt.solve(g);
    if (ldlt.info() != Eigen::Success || !refit.allFinite()) break;
    best = refit;
    double mean = 0.0;
    for (int q = 0; q < m; ++q)
      if (work[q] >= 0) mean += (work[q] = model.bestDepth(q, s[q].du_px, best));
    mean /= used;
    if (!(mean > 1e-6)) break;
    for (int q = 0; q < m; ++q)
      if (work[q] >= 0) work[q] /= mean;
    best.tail<2>() *= mean;
  }
  return true;
}

}  // namespace

int flagInconsistentWindows(std::span<const RingSample> samples,
                            const RingConsensusOptions& options,
                            std::span<std::uint8_t> inconsistent, std::span<double> work) {
  std::fill(inconsistent.begin(), inconsistent.end(), std::uint8_t{0});
  if (static_cast<int>(samples.size()) < kMinSamples || work.size() < 3 * samples.size() ||
      inconsistent.size() < samples.size())
    return 0;
  const int m = static_cast<int>(samples.size());
  const std::span<double> sines = work.subspan(samples.size(), samples.size()),
                          cosines = work.subspan(2 * samples.size(), samples.size());
  for (int q = 0; q < m; ++q) {
    sines[q] = std::sin(samples[q].theta);
    cosines[q] = std::cos(samples[q].theta);
  }
  // The samples' median confidence, before work holds anything else.
  int with_confidence = 0;
  for (const RingSample& q : samples)
    if (hasConfidence(q)) work[with_confidence++] = q.confidence;
  const double median_confidence =
      with_confidence > 0 ? medianOf(work.first(with_confidence)) : 1.0;
  const DuModel du{options.max_inverse_depth, Azimuths{sines, cosines}};
  Sinusoid u;
  double one_depth_sigma = 0.0;
  if (!consensusSinusoid(samples, du, work.first(samples.size()), u, one_depth_sigma)) return 0;
  // Near the translation's axis a window's du says more about the axis's direction than
  // about its depth, and the consensus's direction is not exact enough to judge it there,
  // unless the fit before found the same axis.
  const double amplitude = std::hypot(u(1), u(2));
  constexpr double kDegree = std::numbers::pi / 180.0;
  const bool axis_agrees =
      std::isfinite(options.previous_axis_rad) &&
      std::abs(std::remainder(std::atan2(u(2), u(1)) - options.previous_axis_rad,
                              std::numbers::pi)) < options.agreed_axis_half_width_deg * kDegree;
  const double axis_sin = std::sin(
      (axis_agrees ? options.agreed_axis_half_width_deg : options.axis_half_width_deg) * kDegree);
  const auto residual = [&](int q) {
    if (amplitude > options.floor_px && std::abs(du.azimuths.moving(q, u)) < axis_sin * amplitude)
      return 0.0;
    return du.absorbedResidual(q, samples[q].du_px, u);
  };
  for (int q = 0; q < m; ++q) work[q] = residual(q);
  const double sigma = kMadToSigma * medianOf(work.first(m));
  // With a free depth per window most absorbed residuals are 0 and so is their sigma: the
  // floor is the one-depth fit's noise (the ring's noise when the robot turns in place,
  // the walls' parallax when it drives), within [min_floor_px, floor_px].
  const double floor =
      std::max(std::min(options.sigmas * one_depth_sigma, options.floor_px), options.min_floor_px);
  const double threshold = std::max(options.sigmas * sigma, floor);
  // A weaker peak than the median's: a less certain shift, judged with a wider threshold.
  const auto widening = [&](const RingSample& q) {
    return hasConfidence(q) && q.confidence < median_confidence ? median_confidence / q.confidence
                                                                : 1.0;
  };
  int flagged = 0;
  for (int q = 0; q < m; ++q) {
    inconsistent[q] = residual(q) > threshold * widening(samples[q]) ? kFlagged : 0;
    flagged += inconsistent[q] != 0;
  }
  // The windows beside those flagged, at neighbour_fraction of their threshold (the
  // hysteresis over overlapping windows, above); one step only.
  if (options.neighbour_fraction > 0.0 && flagged > 0) {
    constexpr double kTwoPi = 2.0 * std::numbers::pi;
    const double reach = kNeighbourSpacings * kTwoPi / m;
    for (int q = 0; q < m; ++q) {
      if (inconsistent[q] != kFlagged) continue;
      for (const int j : {(q + m - 1) % m, (q + 1) % m}) {
        if (inconsistent[j] != 0 ||
            std::abs(std::remainder(samples[j].theta - samples[q].theta, kTwoPi)) > reach)
          continue;
        if (residual(j) > options.neighbour_fraction * threshold * widening(samples[j])) {
          inconsistent[j] = kBesideFlagged;
          ++flagged;
        }
      }
    }
  }
  for (int q = 0; q < m; ++q) inconsistent[q] = inconsistent[q] != 0 ? 1 : 0;
  return flagged;
}

}  // namespace omnipose
