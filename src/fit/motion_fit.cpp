#include "omnipose/motion_fit.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <memory>
#include <numbers>
#include <stdexcept>
#include <string>

#include "common/named_values.hpp"
#include "common/periodic.hpp"
#include "common/problem_list.hpp"
#include "omnipose/motion_model.hpp"
#include "omnipose/ring_consensus.hpp"

namespace omnipose {
namespace {

constexpr int kDu = 0, kDv = 1, kRotation = 2, kLogScale = 3;
constexpr double kMadToSigma = 1.4826;
/// Smallest relative standard deviation of a window's equation (Options::window_covariance):
/// a window's variance only ever lowers the weight its confidence gives it. Letting the
/// windows below the median variance weigh up to 4x more (0.5) cost translation direction
/// and park accuracy (docs/results/ANALYSIS.md).
constexpr double kMinRelativeSigma = 1.0;
/// Options::plane_depth_prior: the spread of a window's relative inverse depth around its
/// neighbours' plane, the spread around 1, and the in-window scale equations' weight.
constexpr double kPlaneSigma = 0.15;
constexpr double kPlanePullSigma = 4.0;
constexpr double kPlaneScaleWeight = 0.01;

/// Options::vertical_scale: a window's scale equation weighs (median sigma / its sigma)^2 of
/// the equations' common weight, within these bounds (one window's fit cannot take over, nor
/// vanish for a sigma that its few rows made small or large). Capped at 1 instead (as the du
/// rows' own variance, kMinRelativeSigma) the drift pool's pairs gained about half as much
/// (docs/results/ANALYSIS.md, "The vertical scale in the fit").
constexpr double kMinOwnScaleWeight = 0.05;
constexpr double kMaxOwnScaleWeight = 4.0;

/// Median of a small array (modified in place).
double medianOf(double* begin, int n) {
  std::nth_element(begin, begin + n / 2, begin + n);
  const double upper = begin[n / 2];
  if (n % 2 == 1) return upper;
  const double lower = *std::max_element(begin, begin + n / 2);
  return 0.5 * (lower + upper);
}

}  // namespace

const char* toString(FitStatus status) {
  constexpr detail::Named<FitStatus> kNames[] = {
      {FitStatus::kOk, "ok"}, {FitStatus::kDegraded, "degraded"}, {FitStatus::kLost, "lost"}};
  return detail::nameOf(kNames, status, "unknown");
}

std::vector<std::string> MotionFit::Options::validate() const {
  std::vector<std::string> p;
  detail::checkRange(p, "huber_delta_px", huber_delta_px, 0.0, 100.0, " pixels", true);
  detail::checkRange(p, "median", median, 0, 15, " windows");
  if (median > 1 && median <= 15 && median % 2 == 0)
    p.push_back("median: " + std::to_string(median) + " must be odd (or 0/1 = off)");
  detail::checkRange(p, "median_reject_px", median_reject_px, 0.0, 1000.0, " pixels", true);
  detail::checkRange(p, "max_iterations", max_iterations, 1, 1000);
  detail::checkRange(p, "tolerance", tolerance, 0.0, 1.0, " radians", true);
  detail::checkRange(p, "inlier_sigmas", inlier_sigmas, 0.0, 100.0, "", true);
  detail::checkRange(p, "min_window_fraction", min_window_fraction, 0.0, 1.0);
  detail::checkRange(p, "max_residual_px", max_residual_px, 0.0, 1000.0, " pixels", true);
  detail::checkRange(p, "max_condition", max_condition, 1.0, 1e300, "", true);
  detail::checkRange(p, "depth_prior_sigma", depth_prior_sigma, 0.0, 1000.0, "", true);
  detail::checkRange(p, "scale_depth_gradient", scale_depth_gradient, 0.0, 1.0);
  detail::checkRange(p, "rotation_deformation", rotation_deformation, 0.0, 100.0);
  detail::checkRange(p, "translation_shrinkage", translation_shrinkage, 0.0, 100.0);
  detail::checkRange(p, "planar_motion_deg", planar_motion_deg, 0.0, 45.0, " degrees");
  return p;
}

/// MotionFit's workspace and the steps of fit(); private, so that the public header shows
/// neither the design rows nor the helpers.
struct MotionFit::Impl {
  struct Row {
    Eigen::Matrix<double, 1, 6> a;   ///< design row; translation columns times depth[window]
    Eigen::Matrix<double, 1, 6> a0;  ///< design row for uniform depth
    double b = 0.0;      ///< measurement in model units (radians or ln s)
    double scale = 1.0;  ///< loss pixels per model unit: 1/gamma for du/dv, over the row's
                         ///< relative standard deviation (Options::window_covariance)
    double prior_weight = 1.0;  ///< confidence / noise weight
    double weight = 1.0;        ///< current IRLS weight
    int kind = 0;               ///< 0 du, 1 dv, 2 rotation, 3 log scale
    int window = 0;             ///< index of the window the row belongs to
    double leverage = 0.0;      ///< share of the row absorbed by its window's inverse depth
    double sd = 1.0;  ///< relative standard deviation (Options::window_covariance)
  };

  /// final_weight from the final pass's du and dv rows: each window's sum, over the largest.
  void keepFinalWeights(int n_rows) {
    double largest = 0.0;
    for (int i = 0; i < n_rows; ++i) {
      const Row& row = rows[i];
      if (row.kind != kDu && row.kind != kDv) continue;
      double& w = final_weight[static_cast<std::size_t>(row.window)];
      w += row.weight;
      largest = std::max(largest, w);
    }
    if (largest > 0)
      for (double& w : final_weight) w /= largest;
  }

  /// Options::translation_shrinkage: x's tau scaled by max(0, 1 - K / chi2), chi2 from
  /// `covariance` (the fit's, of independent windows) times the windows' overlap factor, and
  /// its omega solved again from the final pass's normal equations N x = g with that tau.
  void shrinkTranslation(std::span<const WindowMotion> windows,
                         const Eigen::Matrix<double, 6, 6>& N,
                         const Eigen::Matrix<double, 6, 1>& g,
                         const Eigen::Matrix<double, 6, 6>& covariance,
                         Eigen::Matrix<double, 6, 1>& x) {
    // The windows' spacing from the first two (they come in ring order, evenly spaced);
    // the overlap factor is kept for it.
    const int step = windows.size() >= 2
                         ? static_cast<int>(std::lround(windows[1].center_u - windows[0].center_u))
                         : 0;
    if (step != overlap_step) {
      overlap_step = step;
      overlap = step > 0 ? windowOverlapFactor(window_px, step) : 1.0;
    }
    const Eigen::Vector3d tau = x.tail<3>();
    const Eigen::Matrix3d c = overlap * covariance.bottomRightCorner<3, 3>();
    const Eigen::LDLT<Eigen::Matrix3d> c_ldlt(c);
    if (c_ldlt.info() != Eigen::Success) return;
    const double chi2 = tau.dot(c_ldlt.solve(tau));
    if (!std::isfinite(chi2)) return;
    const double factor =
        chi2 > options.translation_shrinkage ? 1.0 - options.translation_shrinkage / chi2 : 0.0;
    if (factor >= 1.0) return;
    x.tail<3>() = factor * tau;
    const Eigen::Vector3d omega = N.topLeftCorner<3, 3>().ldlt().solve(
        g.head<3>() - N.topRightCorner<3, 3>() * x.tail<3>());
    if (omega.allFinite())
      x.head<3>() = omega;
    else
      x.tail<3>() = tau;  // the fit as it was
  }

  /// Allocates the workspace for `max_windows` windows (arguments already validated).
  Impl(const Options& o, double gamma_per_column, int window_size, int max_windows);

  MotionEstimate fit(std::span<const WindowMotion> windows, double forward_column,
                     std::span<const RowScale> row_scale);
  /// Adds the in-window rotation and log-scale rows of the kept windows, weighted by their
  /// own noise relative to the shifts, and runs irls() again on all rows (x and n_rows are
  /// updated, its iterations added). False when that fit failed.
  bool addRotationScaleRows(std::span<const WindowMotion> windows, double forward_column,
                            Eigen::Matrix<double, 6, 1>& x, int& n_rows, int& iterations);
  /// The information matrix of (omega, tau) with the per-window inverse depths as nuisance
  /// parameters: the Schur complement N - N_xl N_ll^-1 N_lx of the inlier rows' normal
  /// matrix N under the gauge constraint; `depth_dof` receives the degrees of freedom the
  /// depths use up (sum of h / (h + prior)).
  Eigen::Matrix<double, 6, 6> depthMarginalInformation(std::span<const WindowMotion> windows,
                                                       int n_rows,
                                                       const Eigen::Matrix<double, 6, 1>& x,
                                                       const Eigen::Matrix<double, 6, 6>& N,
                                                       double& depth_dof);
  int buildTranslationRows(std::span<const WindowMotion> windows, double forward_column,
                           std::span<const RowScale> row_scale);
  /// Relative standard deviations of the kept windows' du or dv (window_covariance):
  /// sqrt(variance / median variance), floored at kMinRelativeSigma; 1 when off or unknown.
  /// `variance(w)` is window w's variance; the median is over the kept windows with one.
  /// Uses scratch[2n, 3n); `out` has n entries.
  template <typename Variance>
  void relativeSigmas(std::span<const WindowMotion> windows, Variance variance, double* out);
  Eigen::Matrix<double, 6, 1> irls(int n_rows, int& iterations, bool& ok);
  double robustSigma(int kind, const Eigen::Matrix<double, 6, 1>& x, int n_rows);
  /// Noise of the shift rows in radians (the larger of du and dv, floored at 0.01 px).
  double shiftSigma(const Eigen::Matrix<double, 6, 1>& x, int n_rows);
  /// Leverage of every row on its window's inverse depth (0 without per-window depth).
  void computeLeverage(std::span<const WindowMotion> windows, int n_rows,
                       const Eigen::Matrix<double, 6, 1>& x);
  /// |residual| in pixels divided by sqrt(1 - leverage).
  double standardizedResidualPx(int i, const Eigen::Matrix<double, 6, 1>& x) const;
  /// Per-window inverse depth: sets the prior weight from the noise and runs
  /// depthGaussNewton (twice, the second time with the depth model's own noise); returns x.
  Eigen::Matrix<double, 6, 1> fitDepth(std::span<const WindowMotion> windows, int n_rows,
                                       Eigen::Matrix<double, 6, 1> x, int& iterations);
  /// Joint Gauss-Newton in (omega, tau) and the per-window inverse depths (in depth),
  /// backtracked on depthCost(); sigma: the shift rows' noise (radians), which sets when a
  /// step is negligible.
  Eigen::Matrix<double, 6, 1> depthGaussNewton(std::span<const WindowMotion> windows,
                                               int n_rows, Eigen::Matrix<double, 6, 1> x,
                                               double sigma, int& iterations);
  /// depthGaussNewton's normal equations at (x, depth), priors included: N and gx of
  /// (omega, tau), and per window k its depth's information h[k], gradient g_lambda[k] and
  /// cross term depth_xl[k].
  void depthNormals(std::span<const WindowMotion> windows, int n_rows,
                    const Eigen::Matrix<double, 6, 1>& x, Eigen::Matrix<double, 6, 6>& N,
                    Eigen::Matrix<double, 6, 1>& gx, double* h, double* g_lambda);
  /// Backtracks the joint step (dx, depth_step) from (x, depth_before): the largest of 1,
  /// 1/2, 1/4, ... that does not raise depthCost() above `cost` is taken (x, depth and
  /// `cost` updated) and returned; 0 when none does (a minimum to rounding: x and the
  /// depths stay).
  double backtrackDepthStep(std::span<const WindowMotion> windows, int n_rows,
                            Eigen::Matrix<double, 6, 1>& x, const Eigen::Matrix<double, 6, 1>& dx,
                            const double* depth_before, const double* depth_step, double& cost);
  /// Sets b of every log-scale row to its window's measured ln s less the horizontal expansion that
  /// the change of inverse depth across the window adds (Options::scale_depth_gradient):
  /// alpha * dlambda/dtheta * D_k, with D_k the translation part of the window's du per
  /// unit inverse depth (radians) and dlambda/dtheta from the neighbouring windows' depths
  /// (the kept ones within two windows on each side; 0 without any). Depends on x and the
  /// current depths, so depthGaussNewton() calls it before every step.
  void depthGradientTerms(std::span<const WindowMotion> windows, int n_rows,
                          const Eigen::Matrix<double, 6, 1>& x);
  /// The robust objective depthGaussNewton() lowers, at x and the current depth.
  double depthCost(std::span<const WindowMotion> windows, int n_rows,
                   const Eigen::Matrix<double, 6, 1>& x) const;

  Options options;
  double gamma;
  int window_px;  ///< window size L
  double kappa;
  int overlap_step = 0;  ///< the window spacing `overlap` was computed for (0: none yet)
  double overlap = 1.0;  ///< windowOverlapFactor(window_px, overlap_step)
  std::vector<Row> rows;
  std::vector<double> scratch;
  std::vector<unsigned char> keep;
  std::vector<double> depth;  ///< relative inverse depth per window (mean 1)
  std::vector<double> final_weight;  ///< per window, MotionFit::finalWeight()
  std::vector<Eigen::Matrix<double, 6, 1>> depth_xl;  ///< N_x,lambda_k columns (covariance)
  double depth_prior_weight = 0.0;  ///< weight of the lambda_k = 1 prior (0: depth not fitted)
  double depth_plane_weight = 0.0;  ///< weight of the neighbours' plane prior (0: off)

  /// Depth is fitted (fitDepth() set a prior).
  bool depthFitted() const { return depth_prior_weight + depth_plane_weight > 0; }
  /// The prior information of lambda_k (its diagonal: both priors, times the confidence).
  double depthPriorInformation(const WindowMotion& w) const {
    return (depth_prior_weight + depth_plane_weight) * w.confidence;
  }
  /// The kept window nearest to k of n on one side (step -1 or +1), within two windows;
  /// -1 if none.
  int keptNeighbour(int k, int step, int n) const {
    for (int j = 1; j <= 2; ++j) {
      const int m = detail::wrapIndex(k + j * step, n);
      if (m != k && keep[m]) return m;
    }
    return -1;
  }
  /// Window k's plane through its nearest kept neighbours (Options::plane_depth_prior):
  /// planeDepth() = w_lo lambda_lo + w_hi lambda_hi.
  struct PlaneNeighbours {
    int lo = -1, hi = -1;  ///< the neighbours (-1: none; a single one is lo)
    double w_lo = 0.0, w_hi = 0.0;
  };
  std::vector<PlaneNeighbours> plane;  ///< per window, planeNeighbours()
  std::vector<RingSample> ring;               ///< the kept windows, ringConsensus()
  std::vector<std::uint8_t> ring_inconsistent;  ///< per entry of `ring`
  std::vector<std::uint8_t> judged_moving;      ///< per window, MotionFit::judgedMoving()
  /// The consensus's options; previous_axis_rad is the translation's axis of the last fit
  /// that moved the windows by more than its floor (NaN before any).
  RingConsensusOptions consensus;
  /// Information of the prior tau_z ~ N(0, sigma_z^2) (Options::planar_motion_deg), in the
  /// units of the rows' normal equations; 0 when there is none.
  double tau_z_information = 0.0;
  /// Sets tau_z_information from the first pass's x.
  void planarMotionPrior(const Eigen::Matrix<double, 6, 1>& x, int n_rows);
  /// irls(), and with Options::planar_motion_deg irls() again with the prior on tau_z its
  /// result sets; `iterations` counts both.
  Eigen::Matrix<double, 6, 1> firstPass(int n_rows, int& iterations, bool& ok);
  /// Leaves out the kept windows that no static scene explains (ring_consensus.hpp).
  void ringConsensus(std::span<const WindowMotion> windows, double forward_column);
  /// The depths' information matrix (max_windows square, so that its factorisation never
  /// reallocates), its factorisation, and the right-hand sides [N_lambda,x | gauge]
  /// (depthMarginalInformation()).
  Eigen::MatrixXd depth_m, depth_rhs;
  Eigen::LLT<Eigen::MatrixXd> depth_llt;
  /// Adds the plane prior's information about the kept windows' depths to depth_m: each
  /// window's residual against its neighbours' plane couples the three depths.
  void planeInformation(std::span<const WindowMotion> windows);
  /// Sets `plane` from the kept windows and their azimuths (depthGaussNewton(), whose
  /// steps and costs keep them: they depend on neither x nor the depths).
  void planeNeighbours(std::span<const WindowMotion> windows);
  /// The inverse depth at window k of the vertical plane through its nearest kept
  /// neighbours' current depths (within two windows on each side): a wall's inverse depth
  /// is A cos(theta) + B sin(theta), fixed by two windows. With one neighbour its depth;
  /// with none depth[k] itself (no pull).
  double planeDepth(int k) const {
    const PlaneNeighbours& p = plane[k];
    if (p.lo < 0) return depth[k];
    return p.w_lo * depth[p.lo] + (p.hi < 0 ? 0.0 : p.w_hi * depth[p.hi]);
  }
};

MotionFit::Impl::Impl(const Options& o, double gamma_per_column, int window_size,
                      int max_windows)
    : options(o),
      gamma(gamma_per_column),
      window_px(window_size),
      kappa(windowAttenuation(window_size, gamma_per_column)),
      rows(4 * static_cast<std::size_t>(max_windows)),
      scratch(rows.size()),
      keep(static_cast<std::size_t>(max_windows)),
      depth(static_cast<std::size_t>(max_windows), 1.0),
      final_weight(static_cast<std::size_t>(max_windows), 0.0),
      depth_xl(static_cast<std::size_t>(max_windows)),
      plane(static_cast<std::size_t>(max_windows)),
      ring(static_cast<std::size_t>(max_windows)),
      ring_inconsistent(static_cast<std::size_t>(max_windows)),
      judged_moving(static_cast<std::size_t>(max_windows), 0),
      depth_m(max_windows, max_windows),
      depth_rhs(max_windows, 7),
      depth_llt(max_windows) {
  // Eigen's LLT leaves its status and norm unset until compute(): factorised once here, so
  // that copying a MotionFit that has not fitted yet copies defined values.
  depth_llt.compute(Eigen::MatrixXd::Identity(max_windows, max_windows));
}

MotionFit::MotionFit(const Options& options, double gamma, int window_px, int max_windows) {
  std::vector<std::string> problems = options.validate();
  detail::checkRange(problems, "gamma", gamma, 0.0, 2 * std::numbers::pi, " radians per column",
                     true);
  detail::checkRange(problems, "window_px", window_px, 1, 65536, " pixels");
  detail::checkRange(problems, "max_windows", max_windows, 1, 65536);
  detail::throwIfProblems("MotionFit", problems);
  impl_ = std::make_unique<Impl>(options, gamma, window_px, max_windows);
}

MotionFit::MotionFit(const MotionFit& other) : impl_(std::make_unique<Impl>(*other.impl_)) {}

MotionFit& MotionFit::operator=(const MotionFit& other) {
  if (this == &other) return *this;
  if (impl_)
    *impl_ = *other.impl_;
  else
    impl_ = std::make_unique<Impl>(*other.impl_);
  return *this;
}

MotionFit::MotionFit(MotionFit&&) noexcept = default;
MotionFit& MotionFit::operator=(MotionFit&&) noexcept = default;
MotionFit::~MotionFit() = default;

MotionEstimate MotionFit::fit(std::span<const WindowMotion> windows, double forward_column,
                              std::span<const RowScale> row_scale) {
  if (!row_scale.empty() && row_scale.size() != windows.size()) {
    MotionEstimate lost;
    lost.windows_total = static_cast<int>(windows.size());
    lost.status = FitStatus::kLost;  // a caller's error: one scale per window
    return lost;
  }
  return impl_->fit(windows, forward_column, row_scale);
}

const MotionFit::Options& MotionFit::options() const { return impl_->options; }

double MotionFit::gamma() const { return impl_->gamma; }

double MotionFit::kappa() const { return impl_->kappa; }

double MotionFit::inverseDepth(int k) const { return impl_->depth[k]; }

double MotionFit::finalWeight(int k) const { return impl_->final_weight[k]; }

bool MotionFit::judgedMoving(int k) const { return impl_->judged_moving[k] != 0; }

int MotionFit::maxWindows() const { return static_cast<int>(impl_->keep.size()); }

int MotionFit::Impl::buildTranslationRows(std::span<const WindowMotion> windows,
                                          double forward_column,
                                          std::span<const RowScale> row_scale) {
  const int n = static_cast<int>(windows.size());
  for (int k = 0; k < n; ++k) keep[k] = windows[k].valid && windows[k].confidence > 0;

  // Median pre-filter over circular neighbours: drop, never replace.
  const int half = options.median > 1 ? options.median / 2 : 0;
  if (half > 0) {
    std::array<double, 16> du_near{}, dv_near{};
    for (int k = 0; k < n; ++k) {
      if (!windows[k].valid || windows[k].confidence <= 0) continue;
      int m = 0;
      for (int j = -half; j <= half; ++j) {
        const WindowMotion& w = windows[detail::wrapIndex(k + j, n)];
        if (!w.valid || w.confidence <= 0) continue;
        du_near[m] = w.du;
        dv_near[m] = w.dv;
        ++m;
      }
      if (m < 3) continue;  // too few neighbours to judge
      const double du_med = medianOf(du_near.data(), m), dv_med = medianOf(dv_near.data(), m);
      if (std::abs(windows[k].du - du_med) > options.median_reject_px ||
          std::abs(windows[k].dv - dv_med) > options.median_reject_px) {
        keep[k] = 0;
      }
    }
  }

  if (options.ring_consensus) ringConsensus(windows, forward_column);

  // Relative standard deviations of du (scratch[0, n)) and dv (scratch[n, 2n)).
  double* const sd_u = scratch.data();
  double* const sd_v = sd_u + n;
  relativeSigmas(windows, [](const WindowMotion& w) { return w.var_du; }, sd_u);
  relativeSigmas(windows, [](const WindowMotion& w) { return w.var_dv; }, sd_v);
  int r = 0;
  for (int k = 0; k < n; ++k) {
    if (!keep[k]) continue;
    const double theta = gamma * (windows[k].center_u - forward_column);
    ModelRows m = modelRows(theta, kappa);
    if (!row_scale.empty()) {
      m.du *= row_scale[k].du;
      m.dv *= row_scale[k].dv;
    }
    const double conf = windows[k].confidence;
    const double cu = conf / (sd_u[k] * sd_u[k]), cv = conf / (sd_v[k] * sd_v[k]);
    rows[r] = Row{m.du, m.du, windows[k].du * gamma, 1.0 / (gamma * sd_u[k]), cu, cu, kDu, k};
    rows[r].sd = sd_u[k];
    rows[r + 1] = Row{m.dv, m.dv, windows[k].dv * gamma, 1.0 / (gamma * sd_v[k]), cv, cv, kDv, k};
    rows[r + 1].sd = sd_v[k];
    r += 2;
  }
  return r;
}

void MotionFit::Impl::ringConsensus(std::span<const WindowMotion> windows,
                                    double forward_column) {
  const int n = static_cast<int>(windows.size());
  int m = 0;
  for (int k = 0; k < n; ++k) {
    if (!keep[k]) continue;
    ring[m++] = RingSample{gamma * (windows[k].center_u - forward_column), windows[k].du,
                           windows[k].confidence};
  }
  const std::span<std::uint8_t> flags(ring_inconsistent.data(), static_cast<std::size_t>(m));
  if (flagInconsistentWindows(std::span<const RingSample>(ring.data(), m), consensus, flags,
                              scratch) == 0)
    return;
  m = 0;
  for (int k = 0; k < n; ++k) {
    if (!keep[k]) continue;
    if (flags[m++]) {
      keep[k] = 0;
      judged_moving[k] = 1;
    }
  }
}

template <typename Variance>
void MotionFit::Impl::relativeSigmas(std::span<const WindowMotion> windows, Variance variance,
                                     double* out) {
  const int n = static_cast<int>(windows.size());
  for (int k = 0; k < n; ++k) out[k] = 1.0;
  if (!options.window_covariance) return;

  // The median over the kept windows with a variance, taken in scratch[2n, 3n).
  double* const known = scratch.data() + 2 * n;
  int m = 0;
  for (int k = 0; k < n; ++k) {
    const double v = variance(windows[k]);
    if (keep[k] && v > 0 && std::isfinite(v)) known[m++] = v;
  }
  if (m == 0) return;
  const double median = medianOf(known, m);
  for (int k = 0; k < n; ++k) {
    const double v = variance(windows[k]);
    if (keep[k] && v > 0 && std::isfinite(v))
      out[k] = std::max(std::sqrt(v / median), kMinRelativeSigma);
  }
}

double MotionFit::Impl::shiftSigma(const Eigen::Matrix<double, 6, 1>& x, int n_rows) {
  return std::max(std::max(robustSigma(kDu, x, n_rows), robustSigma(kDv, x, n_rows)),
                  0.01 * gamma);
}

Eigen::Matrix<double, 6, 1> MotionFit::Impl::firstPass(int n_rows, int& iterations, bool& ok) {
  tau_z_information = 0.0;
  const Eigen::Matrix<double, 6, 1> x = irls(n_rows, iterations, ok);
  if (!ok || !(options.planar_motion_deg > 0)) return x;
  planarMotionPrior(x, n_rows);
  int more = 0;
  const Eigen::Matrix<double, 6, 1> with_prior = irls(n_rows, more, ok);
  iterations += more;
  return with_prior;
}

void MotionFit::Impl::planarMotionPrior(const Eigen::Matrix<double, 6, 1>& x, int n_rows) {
  // The rows' normal equations weigh a residual of sigma_t (the shifts' robust noise) as
  // one; sigma_z in the same units: |tau| sin(angle), and at least kPlanarFloor sigma_t so
  // that a translation of nothing (turning in place) pins tau_z instead of freeing it.
  constexpr double kPlanarFloor = 0.05;
  const double sigma_t = shiftSigma(x, n_rows);
  const double sigma_z =
      std::max(x.tail<3>().norm() * std::sin(options.planar_motion_deg * std::numbers::pi / 180.0),
               kPlanarFloor * sigma_t);
  tau_z_information = (sigma_t / sigma_z) * (sigma_t / sigma_z);
}

double MotionFit::Impl::robustSigma(int kind, const Eigen::Matrix<double, 6, 1>& x, int n_rows) {
  int m = 0;
  for (int i = 0; i < n_rows; ++i) {
    if (rows[i].kind != kind) continue;
    // Standardized by the row's relative standard deviation: the noise of the median window.
    scratch[m++] = std::abs(rows[i].a.dot(x) - rows[i].b) / rows[i].sd;
  }
  if (m == 0) return 0.0;
  return kMadToSigma * medianOf(scratch.data(), m);
}

Eigen::Matrix<double, 6, 1> MotionFit::Impl::irls(int n_rows, int& iterations, bool& ok) {
  using Mat6 = Eigen::Matrix<double, 6, 6>;
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  Vec6 x = Vec6::Zero();
  ok = false;
  for (iterations = 0; iterations < options.max_iterations;) {
    Mat6 N = Mat6::Zero();
    Vec6 g = Vec6::Zero();
    for (int i = 0; i < n_rows; ++i) {
      const Row& row = rows[i];
      if (row.weight <= 0) continue;
      N.noalias() += row.weight * row.a.transpose() * row.a;
      g.noalias() += row.weight * row.b * row.a.transpose();
    }
    N(5, 5) += tau_z_information;
    const Eigen::LDLT<Mat6> ldlt(N);
    if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) return x;
    const Vec6 x_new = ldlt.solve(g);
    if (!x_new.allFinite()) return x;
    ++iterations;
    const double step = (x_new - x).norm();
    x = x_new;
    ok = true;
    // Pseudo-Huber weights: rho'(r)/r = 1 / sqrt(1 + (r/delta)^2), r in pixels.
    for (int i = 0; i < n_rows; ++i) {
      Row& row = rows[i];
      const double r_px = (row.a.dot(x) - row.b) * row.scale / options.huber_delta_px;
      row.weight = row.prior_weight / std::sqrt(1.0 + r_px * r_px);
    }
    if (step < options.tolerance) break;
  }
  return x;
}

Eigen::Matrix<double, 6, 1> MotionFit::Impl::fitDepth(std::span<const WindowMotion> windows,
                                                       int n_rows, Eigen::Matrix<double, 6, 1> x,
                                                       int& iterations) {
  const int n = static_cast<int>(windows.size());
  // Prior lambda_k ~ N(1, sigma_lambda), expressed in the units of the shift rows
  // (radians) so that it weighs against them by their noise. First with the uniform fit's residual scale (inflated by the depth misfit), then with
  // the depth model's own standardized residuals, so that the prior weighs against the
  // measurement noise and not against the misfit it is there to remove.
  double sigma_t = shiftSigma(x, n_rows);
  for (int k = 0; k < n; ++k) depth[k] = 1.0;
  for (int round = 0; round < 2; ++round) {
    if (round == 1) {
      computeLeverage(windows, n_rows, x);
      int m = 0;
      for (int i = 0; i < n_rows; ++i) {
        if (rows[i].kind == kDu || rows[i].kind == kDv)
          scratch[m++] = standardizedResidualPx(i, x) / (rows[i].scale * rows[i].sd);
      }
      if (m == 0) break;
      sigma_t = std::max(kMadToSigma * medianOf(scratch.data(), m), 0.01 * gamma);
    }
    const bool plane = options.plane_depth_prior;
    const double ratio = sigma_t / (plane ? kPlanePullSigma : options.depth_prior_sigma);
    depth_prior_weight = ratio * ratio;
    const double plane_ratio = plane ? sigma_t / kPlaneSigma : 0.0;
    depth_plane_weight = plane_ratio * plane_ratio;
    x = depthGaussNewton(windows, n_rows, x, sigma_t, iterations);
  }
  return x;
}

void MotionFit::Impl::planeNeighbours(std::span<const WindowMotion> windows) {
  const int n = static_cast<int>(windows.size());
  constexpr double kTwoPi = 2.0 * std::numbers::pi;
  for (int k = 0; k < n; ++k) {
    PlaneNeighbours& p = plane[k];
    p = PlaneNeighbours{};
    const int lo = keptNeighbour(k, -1, n), hi = keptNeighbour(k, +1, n);
    if (lo < 0 && hi < 0) continue;
    if (lo < 0 || hi < 0 || hi == lo) {  // one neighbour: its depth
      p.lo = lo < 0 ? hi : lo;
      p.w_lo = 1.0;
      continue;
    }
    p.lo = lo;
    p.hi = hi;
    const double a = std::remainder(gamma * (windows[k].center_u - windows[lo].center_u), kTwoPi);
    const double b = std::remainder(gamma * (windows[hi].center_u - windows[k].center_u), kTwoPi);
    const double span = std::sin(a + b);
    if (!(std::abs(span) > 1e-6)) {
      p.w_lo = p.w_hi = 0.5;
    } else {
      p.w_lo = std::sin(b) / span;
      p.w_hi = std::sin(a) / span;
    }
  }
}

double MotionFit::Impl::depthCost(std::span<const WindowMotion> windows, int n_rows,
                                  const Eigen::Matrix<double, 6, 1>& x) const {
  // sum_i c_i rho(r_i s) / s^2 + 1/2 sum_k h_k (lambda_k - 1)^2: the objective whose
  // stationary point the IRLS-weighted Gauss-Newton step solves for (rho pseudo-Huber, r_i
  // in model units, s pixels per model unit, c_i the row's prior weight). With the plane
  // prior, plus 1/2 sum_k p_k (lambda_k - plane_k)^2; the step holds each plane_k at the
  // neighbours' depths it starts from (not this cost's exact gradient), and the
  // backtracking keeps the cost from rising and stops when no step lowers it.
  const double delta = options.huber_delta_px;
  double cost = 0.0;
  for (int i = 0; i < n_rows; ++i) {
    const Row& row = rows[i];
    if (row.prior_weight <= 0) continue;
    const double r = row.a0.head<3>().dot(x.head<3>()) +
                     depth[row.window] * row.a0.tail<3>().dot(x.tail<3>()) - row.b;
    const double z = r * row.scale / delta;
    cost += row.prior_weight * delta * delta * (std::sqrt(1.0 + z * z) - 1.0) /
            (row.scale * row.scale);
  }
  const int n = static_cast<int>(windows.size());
  for (int k = 0; k < n; ++k) {
    const double d = depth[k] - 1.0;
    cost += 0.5 * depth_prior_weight * windows[k].confidence * d * d;
    if (depth_plane_weight <= 0) continue;
    const double e = depth[k] - planeDepth(k);
    cost += 0.5 * depth_plane_weight * windows[k].confidence * e * e;
  }
  cost += 0.5 * tau_z_information * x(5) * x(5);
  return cost;
}

void MotionFit::Impl::depthNormals(std::span<const WindowMotion> windows, int n_rows,
                                   const Eigen::Matrix<double, 6, 1>& x,
                                   Eigen::Matrix<double, 6, 6>& N,
                                   Eigen::Matrix<double, 6, 1>& gx, double* h, double* g_lambda) {
  const int n = static_cast<int>(windows.size());
  N.setZero();
  gx.setZero();
  for (int k = 0; k < n; ++k) {
    const double prior = depth_prior_weight * windows[k].confidence;
    depth_xl[k].setZero();
    h[k] = depthPriorInformation(windows[k]);
    g_lambda[k] = prior * (1.0 - depth[k]);
    // The plane prior's mean is taken at the neighbours' depths this step starts from.
    if (depth_plane_weight > 0)
      g_lambda[k] += depth_plane_weight * windows[k].confidence *
                     (planeDepth(k) - depth[k]);
  }
  for (int i = 0; i < n_rows; ++i) {
    const Row& row = rows[i];
    if (row.weight <= 0) continue;
    const int k = row.window;
    Eigen::Matrix<double, 1, 6> Jx = row.a0;
    Jx.tail<3>() *= depth[k];
    const double Jl = row.a0.tail<3>().dot(x.tail<3>());
    const double r = row.b - Jx.dot(x);
    N.noalias() += row.weight * Jx.transpose() * Jx;
    gx.noalias() += row.weight * r * Jx.transpose();
    depth_xl[k].noalias() += row.weight * Jl * Jx.transpose();
    h[k] += row.weight * Jl * Jl;
    g_lambda[k] += row.weight * Jl * r;
  }
  N(5, 5) += tau_z_information;
  gx(5) -= tau_z_information * x(5);
}

double MotionFit::Impl::backtrackDepthStep(std::span<const WindowMotion> windows, int n_rows,
                                           Eigen::Matrix<double, 6, 1>& x,
                                           const Eigen::Matrix<double, 6, 1>& dx,
                                           const double* depth_before, const double* depth_step,
                                           double& cost) {
  constexpr int kMaxHalvings = 6;
  const int n = static_cast<int>(windows.size());
  const Eigen::Matrix<double, 6, 1> x_before = x;
  double t = 1.0;
  for (int halving = 0; halving <= kMaxHalvings; ++halving, t *= 0.5) {
    x = x_before + t * dx;
    for (int k = 0; k < n; ++k)
      depth[k] = std::clamp(depth_before[k] + t * depth_step[k], 0.25, 4.0);
    const double trial = depthCost(windows, n_rows, x);
    if (trial <= cost) {
      cost = trial;
      return t;
    }
  }
  x = x_before;
  for (int k = 0; k < n; ++k) depth[k] = depth_before[k];
  return 0.0;
}

Eigen::Matrix<double, 6, 1> MotionFit::Impl::depthGaussNewton(
    std::span<const WindowMotion> windows, int n_rows, Eigen::Matrix<double, 6, 1> x,
    double sigma, int& iterations) {
  using Mat6 = Eigen::Matrix<double, 6, 6>;
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  const int n = static_cast<int>(windows.size());
  // scratch: [0, n) h_k, [n, 2n) g_lambda_k, [2n, 3n) lambda_k before the step,
  // [3n, 4n) the lambda_k step (rows.size() = scratch.size() >= 4 n).
  double* const h = scratch.data();
  double* const g_lambda = h + n;
  double* const depth_before = h + 2 * n;
  double* const depth_step = h + 3 * n;
  planeNeighbours(windows);

  // Gauss-Newton on the bilinear model b = a_rot omega + lambda_k a_tr tau, jointly in
  // (x, lambda) with the pseudo-Huber weights of the current point, eliminating the lambda
  // (diagonal block) by the Schur complement. Every step is backtracked until it lowers
  // depthCost(), and the iteration stops once a step moves (omega, tau) by less than
  // kNegligibleStep standard deviations (its Mahalanobis length under the reduced
  // information matrix S and the shift noise `sigma`, radians); it used to stop on
  // |dx| < 1e-9, which it almost never reached: where tau is small against the noise,
  // lambda and tau are barely observable and the steps crept along that valley until the
  // 20-iteration cap. A looser kNegligibleStep (1e-2) and Newton's Hessian cost accuracy
  // (docs/PERFORMANCE.md).
  constexpr double kNegligibleStep = 1e-3;
  double total = 0.0;
  for (int k = 0; k < n; ++k) total += keep[k] ? windows[k].confidence : 0.0;
  const auto gauge = [&](int k) {
    return keep[k] && total > 0 ? windows[k].confidence / total : 0.0;
  };
  double cost = 0.0;
  for (int pass = 0; pass < options.max_iterations; ++pass) {
    // The depth-gradient terms move with x and the depths: the step of this pass, and the
    // backtracking's costs, use the terms of the point it starts from.
    depthGradientTerms(windows, n_rows, x);
    cost = depthCost(windows, n_rows, x);
    Mat6 N;
    Vec6 gx;
    depthNormals(windows, n_rows, x, N, gx, h, g_lambda);
    // Gauge: sum_k c_k lambda_k = 1 (c_k = gauge(k)), a hard constraint that keeps
    // tau = t / (mean scene distance). Eliminating lambda and the multiplier:
    // (N - B D^-1 B^T + v v^T / q) dx = g_x - B D^-1 g_l + v (c^T D^-1 g_l - e) / q,
    // v = B D^-1 c, q = c^T D^-1 c, e = 1 - c^T lambda.
    Mat6 S = N;
    Vec6 rhs = gx;
    Vec6 v = Vec6::Zero();
    double q = 0.0, cg = 0.0, e = 1.0;
    // A window without information about its depth (no rows and a confidence of 0: masked,
    // without a peak, or left out as moving content) has none to eliminate: its depth
    // stays. (Dividing by its h of 0 made the whole step NaN, and every depth stayed 1.)
    for (int k = 0; k < n; ++k) {
      if (!(h[k] > 0)) continue;
      const double c = gauge(k);
      S.noalias() -= depth_xl[k] * depth_xl[k].transpose() / h[k];
      rhs.noalias() -= depth_xl[k] * (g_lambda[k] / h[k]);
      v.noalias() += depth_xl[k] * (c / h[k]);
      q += c * c / h[k];
      cg += c * g_lambda[k] / h[k];
      e -= c * depth[k];
    }
    double mu_scale = 0.0;
    if (q > 0) {
      S.noalias() += v * v.transpose() / q;
      rhs.noalias() += v * ((cg - e) / q);
      mu_scale = 1.0 / q;
    }
    const Eigen::LDLT<Mat6> ldlt(S);
    if (ldlt.info() != Eigen::Success || !ldlt.isPositive()) break;
    const Vec6 dx = ldlt.solve(rhs);
    if (!dx.allFinite()) break;
    const double mu = mu_scale * (cg - v.dot(dx) - e);  // Lagrange multiplier
    for (int k = 0; k < n; ++k) {
      depth_before[k] = depth[k];
      depth_step[k] =
          h[k] > 0 ? (g_lambda[k] - depth_xl[k].dot(dx) - gauge(k) * mu) / h[k] : 0.0;
    }
    // Backtracked; no step lowers the cost (a minimum to rounding): stay and stop.
    const double t = backtrackDepthStep(windows, n_rows, x, dx, depth_before, depth_step, cost);
    const bool lowered = t > 0;
    ++iterations;
    for (int i = 0; i < n_rows; ++i) {
      Row& row = rows[i];
      row.a.head<3>() = row.a0.head<3>();
      row.a.tail<3>() = depth[row.window] * row.a0.tail<3>();
      const double r_px = (row.a.dot(x) - row.b) * row.scale / options.huber_delta_px;
      row.weight = row.prior_weight / std::sqrt(1.0 + r_px * r_px);
    }
    if (!lowered) break;
    const double step_sigmas = t * std::sqrt(std::max(dx.dot(S * dx), 0.0)) / sigma;
    if (t * dx.norm() < options.tolerance || step_sigmas < kNegligibleStep) break;
  }
  return x;
}

void MotionFit::Impl::depthGradientTerms(std::span<const WindowMotion> windows, int n_rows,
                                         const Eigen::Matrix<double, 6, 1>& x) {
  // A vertical scale has no horizontal expansion to take out (Options::vertical_scale).
  const double alpha = options.vertical_scale ? 0.0 : options.scale_depth_gradient;
  if (alpha == 0.0) return;
  const int n = static_cast<int>(windows.size());
  for (int i = 0; i < n_rows; ++i) {
    Row& row = rows[i];
    if (row.kind != kLogScale) continue;
    const int k = row.window;
    row.b = std::log(windows[k].scale);  // as measured, and as fit() wrote it
    int lo = keptNeighbour(k, -1, n), hi = keptNeighbour(k, +1, n);
    if (lo < 0 && hi < 0) continue;
    if (lo < 0) lo = k;
    if (hi < 0) hi = k;
    const double span = std::remainder(gamma * (windows[hi].center_u - windows[lo].center_u),
                                       2.0 * std::numbers::pi);
    if (!(std::abs(span) > 0)) continue;
    const double slope = (depth[hi] - depth[lo]) / span;
    // The du row's translation columns are (-kappa sin, kappa cos, 0), the log-scale row's
    // (-kappa cos, -kappa sin, 0): D_k = -kappa sin(theta) tau_x + kappa cos(theta) tau_y.
    const double D = row.a0(4) * x(3) - row.a0(3) * x(4);
    row.b -= alpha * slope * D;
  }
}

void MotionFit::Impl::computeLeverage(std::span<const WindowMotion> windows, int n_rows,
                                      const Eigen::Matrix<double, 6, 1>& x) {
  for (int i = 0; i < n_rows; ++i) rows[i].leverage = 0.0;
  if (!options.per_window_depth || !depthFitted()) return;
  const int n = static_cast<int>(windows.size());
  for (int k = 0; k < n; ++k) scratch[k] = depthPriorInformation(windows[k]);
  for (int i = 0; i < n_rows; ++i) {
    const double J = rows[i].a0.tail<3>().dot(x.tail<3>());
    scratch[rows[i].window] += rows[i].weight * J * J;
  }
  for (int i = 0; i < n_rows; ++i) {
    const double J = rows[i].a0.tail<3>().dot(x.tail<3>());
    rows[i].leverage = rows[i].weight * J * J / scratch[rows[i].window];
  }
}

double MotionFit::Impl::standardizedResidualPx(int i,
                                               const Eigen::Matrix<double, 6, 1>& x) const {
  const Row& row = rows[i];
  const double r_px = std::abs((row.a.dot(x) - row.b) * row.scale);
  return r_px / std::sqrt(std::max(1.0 - row.leverage, 0.05));
}

bool MotionFit::Impl::addRotationScaleRows(std::span<const WindowMotion> windows,
                                           double forward_column, Eigen::Matrix<double, 6, 1>& x,
                                           int& n_rows, int& iterations) {
  const double sigma_t = shiftSigma(x, n_rows);
  const int n_trans = n_rows;
  for (std::size_t k = 0; k < windows.size(); ++k) {
    if (!keep[k] || windows[k].rs_confidence <= 0 || !(windows[k].scale > 0)) continue;
    const double theta = gamma * (windows[k].center_u - forward_column);
    const ModelRows m = modelRows(theta, kappa);
    const double conf = windows[k].rs_confidence;
    const int w = static_cast<int>(k);
    rows[n_rows++] =
        Row{m.rotation, m.rotation, windows[k].rotation, 1.0, conf, conf, kRotation, w};
    if (!options.vertical_scale)
      rows[n_rows++] = Row{m.log_scale, m.log_scale, std::log(windows[k].scale), 1.0, conf,
                           conf, kLogScale, w};
    else if (windows[k].vertical_scale_sigma > 0 && windows[k].vertical_scale > 0)
      rows[n_rows++] = Row{m.log_scale, m.log_scale, std::log(windows[k].vertical_scale), 1.0,
                           conf, conf, kLogScale, w};
  }
  if (n_rows > n_trans) {
    const double floor_rs = 1e-4;
    // The rotation equations' error under translation (Options::rotation_deformation),
    // in quadrature with their scatter.
    const double deformation = options.rotation_deformation * x.tail<3>().norm();
    const double sigma_r = std::hypot(std::max(robustSigma(kRotation, x, n_rows), floor_rs),
                                      deformation);
    const double sigma_s = std::max(robustSigma(kLogScale, x, n_rows), floor_rs);
    // Options::vertical_scale: each window's scale equation by its own fit's sigma.
    double median_sigma = 0.0;
    if (options.vertical_scale) {
      int m = 0;
      for (int i = n_trans; i < n_rows; ++i)
        if (rows[i].kind == kLogScale)
          scratch[m++] = windows[rows[i].window].vertical_scale_sigma;
      if (m > 0) median_sigma = medianOf(scratch.data(), m);
    }
    for (int i = n_trans; i < n_rows; ++i) {
      Row& row = rows[i];
      const double sigma = row.kind == kRotation ? sigma_r : sigma_s;
      if (row.kind == kLogScale && median_sigma > 0) {
        const double ratio = median_sigma / windows[row.window].vertical_scale_sigma;
        row.prior_weight *= std::clamp(ratio * ratio, kMinOwnScaleWeight, kMaxOwnScaleWeight);
      }
      // Residuals expressed in "equivalent shift pixels" for the loss, weights by 1/var.
      row.scale = sigma_t / sigma / gamma;
      row.prior_weight *= (sigma_t / sigma) * (sigma_t / sigma);
      if (row.kind == kLogScale && options.plane_depth_prior)
        row.prior_weight *= kPlaneScaleWeight;
      row.weight = row.prior_weight;
    }
    for (int i = 0; i < n_trans; ++i) rows[i].weight = rows[i].prior_weight;
    int more = 0;
    bool ok = false;
    x = irls(n_rows, more, ok);
    iterations += more;
    return ok;
  }
  return true;
}

Eigen::Matrix<double, 6, 6> MotionFit::Impl::depthMarginalInformation(
    std::span<const WindowMotion> windows, int n_rows, const Eigen::Matrix<double, 6, 1>& x,
    const Eigen::Matrix<double, 6, 6>& N, double& depth_dof) {
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  Eigen::Matrix<double, 6, 6> information = N;
  depth_dof = 0.0;
  const int n = static_cast<int>(windows.size());
  for (int k = 0; k < n; ++k) {
    depth_xl[k].setZero();
    scratch[k] = 0.0;
  }
  for (int i = 0; i < n_rows; ++i) {
    const Row& row = rows[i];
    if (row.weight <= 0) continue;
    const double J = row.a0.tail<3>().dot(x.tail<3>());  // d(prediction)/d(lambda_k)
    depth_xl[row.window].noalias() += row.weight * J * row.a.transpose();
    scratch[row.window] += row.weight * J * J;
  }
  double total = 0.0;
  for (int k = 0; k < n; ++k) total += keep[k] ? windows[k].confidence : 0.0;
  // The depths' information M: from the rows and the pull towards 1 on the diagonal, and
  // with the plane prior its coupling of each window's depth to its neighbours'
  // (planeInformation()). Eliminated with the gauge constraint (weights c):
  // N - B M^-1 B^T + v v^T / q, v = B M^-1 c, q = c^T M^-1 c. Windows not kept have none.
  const int m = static_cast<int>(depth_m.rows());
  depth_m.setZero();
  depth_rhs.setZero();
  for (int k = 0; k < n; ++k) {
    if (!keep[k]) continue;
    depth_m(k, k) = scratch[k] + depth_prior_weight * windows[k].confidence;
    depth_rhs.row(k).head<6>() = depth_xl[k].transpose();
    depth_rhs(k, 6) = total > 0 ? windows[k].confidence / total : 0.0;
  }
  planeInformation(windows);
  for (int k = 0; k < m; ++k) {
    if (k < n && keep[k] && depth_m(k, k) > 0) depth_dof += scratch[k] / depth_m(k, k);
    if (!(depth_m(k, k) > 0)) depth_m(k, k) = 1.0;  // no information (nothing couples it)
  }
  depth_llt.compute(depth_m);
  if (depth_llt.info() != Eigen::Success) return information;
  depth_llt.solveInPlace(depth_rhs);
  Vec6 v = Vec6::Zero();
  double q = 0.0;
  for (int k = 0; k < n; ++k) {
    if (!keep[k]) continue;
    information.noalias() -= depth_xl[k] * depth_rhs.row(k).head<6>();
    v.noalias() += depth_xl[k] * depth_rhs(k, 6);
    q += depth_rhs(k, 6) * (total > 0 ? windows[k].confidence / total : 0.0);
  }
  if (q > 0) information.noalias() += v * v.transpose() / q;  // the gauge constraint
  return information;
}

void MotionFit::Impl::planeInformation(std::span<const WindowMotion> windows) {
  if (depth_plane_weight <= 0) return;
  const int n = static_cast<int>(windows.size());
  planeNeighbours(windows);
  // 1/2 p_k e_k^2 with e_k = lambda_k - w_lo lambda_lo - w_hi lambda_hi: p_k g g^T, g = (1,
  // -w_lo, -w_hi) at (k, lo, hi).
  for (int k = 0; k < n; ++k) {
    const PlaneNeighbours& pn = plane[k];
    const double p = depth_plane_weight * windows[k].confidence;
    if (!keep[k] || pn.lo < 0 || !(p > 0)) continue;
    const std::array<int, 3> idx{k, pn.lo, pn.hi};
    const std::array<double, 3> g{1.0, -pn.w_lo, -pn.w_hi};
    for (int i = 0; i < 3; ++i)
      for (int j = 0; j < 3; ++j)
        if (idx[i] >= 0 && idx[j] >= 0) depth_m(idx[i], idx[j]) += p * g[i] * g[j];
  }
}

MotionEstimate MotionFit::Impl::fit(std::span<const WindowMotion> windows,
                                    double forward_column, std::span<const RowScale> row_scale) {
  using Mat6 = Eigen::Matrix<double, 6, 6>;
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  MotionEstimate est;
  est.windows_total = static_cast<int>(windows.size());
  est.windows_masked = static_cast<int>(
      std::count_if(windows.begin(), windows.end(), [](const WindowMotion& w) { return w.masked; }));
  std::fill(judged_moving.begin(), judged_moving.end(), std::uint8_t{0});
  if (windows.size() > keep.size()) {
    est.status = FitStatus::kLost;  // workspace too small: configuration error upstream
    return est;
  }
  depth_prior_weight = 0.0;
  depth_plane_weight = 0.0;
  std::fill(depth.begin(), depth.end(), 1.0);  // inverseDepth() when depth is not fitted
  std::fill(final_weight.begin(), final_weight.end(), 0.0);  // until the final pass
  int n_rows = buildTranslationRows(windows, forward_column, row_scale);
  if (n_rows < 2 * kMinWindows) return est;  // du and dv rows of too few windows: nothing to fit

  bool ok = false;
  Vec6 x = firstPass(n_rows, est.iterations, ok);
  if (!ok) return est;

  // In-window rotation and scale, weighted by their own noise relative to the shifts.
  if (options.use_rotation_scale &&
      !addRotationScaleRows(windows, forward_column, x, n_rows, est.iterations))
    return est;

  if (options.per_window_depth) x = fitDepth(windows, n_rows, x, est.iterations);

  // Final least-squares pass on the inliers, judged by standardized residuals: a window's
  // inverse depth absorbs part of its rows' residuals (leverage w J^2 / h), which would
  // otherwise make the robust sigma too small and reject good windows.
  computeLeverage(windows, n_rows, x);
  int m = 0;
  for (int i = 0; i < n_rows; ++i) scratch[m++] = standardizedResidualPx(i, x);
  const double sigma_px = kMadToSigma * medianOf(scratch.data(), m);
  const double threshold = std::max(options.inlier_sigmas * sigma_px, 0.1);
  Mat6 N = Mat6::Zero();
  Vec6 g = Vec6::Zero();
  int used_rows = 0;
  for (int i = 0; i < n_rows; ++i) {
    Row& row = rows[i];
    row.weight = standardizedResidualPx(i, x) < threshold ? row.prior_weight : 0.0;
    if (row.weight <= 0) continue;
    N.noalias() += row.weight * row.a.transpose() * row.a;
    g.noalias() += row.weight * row.b * row.a.transpose();
    ++used_rows;
  }
  N(5, 5) += tau_z_information;
  const Eigen::SelfAdjointEigenSolver<Mat6> eig(N, Eigen::EigenvaluesOnly);
  const double lmin = eig.eigenvalues()(0), lmax = eig.eigenvalues()(5);
  if (used_rows < 8 || !(lmin > 0) || lmax / lmin > options.max_condition) return est;
  const Eigen::LDLT<Mat6> ldlt(N);
  x = ldlt.solve(g);
  if (!x.allFinite()) return est;
  keepFinalWeights(n_rows);

  // Residual statistics and covariance sigma^2 N^-1 (model units).
  double wrr = 0.0, shift_rr = 0.0;
  int shift_n = 0;
  for (int i = 0; i < n_rows; ++i) {
    const Row& row = rows[i];
    if (row.weight <= 0) continue;
    const double r = row.a.dot(x) - row.b;
    wrr += row.weight * r * r;
    if (row.kind == kDu || row.kind == kDv) {
      shift_rr += (r / gamma) * (r / gamma);
      ++shift_n;
    }
  }
  // With per-window depth, lambda are nuisance parameters: the covariance of (omega, tau)
  // is the inverse of the Schur complement N - N_xl N_ll^-1 N_lx (N_ll diagonal: each row
  // has one lambda) under the gauge constraint, and each lambda uses up h/(h + prior)
  // degrees of freedom.
  Mat6 information = N;
  double depth_dof = 0.0;
  if (options.per_window_depth && depthFitted())
    information = depthMarginalInformation(windows, n_rows, x, N, depth_dof);
  const double dof = std::max(used_rows - 6 - depth_dof, 1.0);
  const Eigen::LDLT<Mat6> marginal(information);
  est.covariance = (wrr / dof) * marginal.solve(Mat6::Identity());
  est.residual_rms_px = shift_n > 0 ? std::sqrt(shift_rr / shift_n) : 0.0;
  est.windows_used = (shift_n + 1) / 2;  // du and dv rows of a window count once
  if (options.translation_shrinkage > 0) shrinkTranslation(windows, N, g, est.covariance, x);
  est.omega = x.head<3>();
  est.tau = x.tail<3>();

  const bool few =
      est.windows_used < options.min_window_fraction * (est.windows_total - est.windows_masked);
  est.status = (few || est.residual_rms_px > options.max_residual_px) ? FitStatus::kDegraded
                                                                        : FitStatus::kOk;
  // du's translation part, kappa (-tau_x sin + tau_y cos) / gamma pixels (modelRows()), as
  // the consensus writes it: b sin + c cos.
  const double b = -kappa * est.tau(0) / gamma, c = kappa * est.tau(1) / gamma;
  if (est.status == FitStatus::kOk && std::hypot(b, c) > consensus.floor_px)
    consensus.previous_axis_rad = std::atan2(c, b);
  return est;
}

}  // namespace omnipose
