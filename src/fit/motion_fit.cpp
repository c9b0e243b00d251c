#include "omnipose/motion_fit.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>
#include <stdexcept>
#include <string>

#include "common/problem_list.hpp"
#include "omnipose/motion_model.hpp"

namespace omnipose {
namespace {

constexpr int kDu = 0, kDv = 1, kRotation = 2, kLogScale = 3;
constexpr double kMadToSigma = 1.4826;

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
  switch (status) {
    case FitStatus::kOk: return "ok";
    case FitStatus::kDegraded: return "degraded";
    case FitStatus::kLost: return "lost";
  }
  return "unknown";
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
  return p;
}

MotionFit::MotionFit(const Options& options, double gamma, int window_px, int max_windows)
    : options_(options),
      gamma_(gamma),
      kappa_(window_px >= 1 && gamma > 0 ? windowAttenuation(window_px, gamma) : 1.0) {
  std::vector<std::string> problems = options.validate();
  detail::checkRange(problems, "gamma", gamma, 0.0, 2 * std::numbers::pi, " radians per column",
                     true);
  detail::checkRange(problems, "window_px", window_px, 1, 65536, " pixels");
  detail::checkRange(problems, "max_windows", max_windows, 1, 65536);
  detail::throwIfProblems("MotionFit", problems);
  rows_.resize(4 * static_cast<std::size_t>(max_windows));
  scratch_.resize(rows_.size());
  keep_.resize(max_windows);
  depth_.assign(max_windows, 1.0);
  depth_xl_.resize(max_windows);
}

int MotionFit::buildTranslationRows(std::span<const WindowMotion> windows, double forward_column) {
  const int n = static_cast<int>(windows.size());
  for (int k = 0; k < n; ++k) keep_[k] = windows[k].valid && windows[k].confidence > 0;

  // Median pre-filter over circular neighbours: drop, never replace.
  const int half = options_.median > 1 ? options_.median / 2 : 0;
  if (half > 0) {
    std::array<double, 16> du_near{}, dv_near{};
    for (int k = 0; k < n; ++k) {
      if (!windows[k].valid || windows[k].confidence <= 0) continue;
      int m = 0;
      for (int j = -half; j <= half; ++j) {
        const WindowMotion& w = windows[((k + j) % n + n) % n];
        if (!w.valid || w.confidence <= 0) continue;
        du_near[m] = w.du;
        dv_near[m] = w.dv;
        ++m;
      }
      if (m < 3) continue;  // too few neighbours to judge
      const double du_med = medianOf(du_near.data(), m), dv_med = medianOf(dv_near.data(), m);
      if (std::abs(windows[k].du - du_med) > options_.median_reject_px ||
          std::abs(windows[k].dv - dv_med) > options_.median_reject_px) {
        keep_[k] = 0;
      }
    }
  }

  int r = 0;
  for (int k = 0; k < n; ++k) {
    if (!keep_[k]) continue;
    const double theta = gamma_ * (windows[k].center_u - forward_column);
    const ModelRows m = modelRows(theta, kappa_);
    const double conf = windows[k].confidence;
    rows_[r] = Row{m.du, m.du, windows[k].du * gamma_, 1.0 / gamma_, conf, conf, kDu, k};
    rows_[r + 1] = Row{m.dv, m.dv, windows[k].dv * gamma_, 1.0 / gamma_, conf, conf, kDv, k};
    r += 2;
  }
  return r;
}

double MotionFit::shiftSigma(const Eigen::Matrix<double, 6, 1>& x, int n_rows) {
  return std::max(std::max(robustSigma(kDu, x, n_rows), robustSigma(kDv, x, n_rows)),
                  0.01 * gamma_);
}

double MotionFit::robustSigma(int kind, const Eigen::Matrix<double, 6, 1>& x, int n_rows) {
  int m = 0;
  for (int i = 0; i < n_rows; ++i) {
    if (rows_[i].kind != kind) continue;
    scratch_[m++] = std::abs(rows_[i].a.dot(x) - rows_[i].b);
  }
  if (m == 0) return 0.0;
  return kMadToSigma * medianOf(scratch_.data(), m);
}

Eigen::Matrix<double, 6, 1> MotionFit::irls(int n_rows, int& iterations, bool& ok) {
  using Mat6 = Eigen::Matrix<double, 6, 6>;
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  Vec6 x = Vec6::Zero();
  ok = false;
  for (iterations = 0; iterations < options_.max_iterations;) {
    Mat6 N = Mat6::Zero();
    Vec6 g = Vec6::Zero();
    for (int i = 0; i < n_rows; ++i) {
      const Row& row = rows_[i];
      if (row.weight <= 0) continue;
      N.noalias() += row.weight * row.a.transpose() * row.a;
      g.noalias() += row.weight * row.b * row.a.transpose();
    }
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
      Row& row = rows_[i];
      const double r_px = (row.a.dot(x) - row.b) * row.scale / options_.huber_delta_px;
      row.weight = row.prior_weight / std::sqrt(1.0 + r_px * r_px);
    }
    if (step < options_.tolerance) break;
  }
  return x;
}

Eigen::Matrix<double, 6, 1> MotionFit::fitDepth(std::span<const WindowMotion> windows,
                                                 int n_rows, Eigen::Matrix<double, 6, 1> x,
                                                 int& iterations) {
  const int n = static_cast<int>(windows.size());
  // Prior lambda_k ~ N(1, sigma_lambda), expressed in the units of the shift rows
  // (radians) so that it weighs against them by their noise. First with the uniform fit's residual scale (inflated by the depth misfit), then with
  // the depth model's own standardized residuals, so that the prior weighs against the
  // measurement noise and not against the misfit it is there to remove.
  double sigma_t = shiftSigma(x, n_rows);
  for (int k = 0; k < n; ++k) depth_[k] = 1.0;
  for (int round = 0; round < 2; ++round) {
    if (round == 1) {
      computeLeverage(windows, n_rows, x);
      int m = 0;
      for (int i = 0; i < n_rows; ++i) {
        if (rows_[i].kind == kDu || rows_[i].kind == kDv)
          scratch_[m++] = standardizedResidualPx(i, x) / rows_[i].scale;
      }
      if (m == 0) break;
      sigma_t = std::max(kMadToSigma * medianOf(scratch_.data(), m), 0.01 * gamma_);
    }
    const double ratio = sigma_t / options_.depth_prior_sigma;
    depth_prior_weight_ = ratio * ratio;
    x = depthGaussNewton(windows, n_rows, x, sigma_t, iterations);
  }
  return x;
}

double MotionFit::depthCost(std::span<const WindowMotion> windows, int n_rows,
                            const Eigen::Matrix<double, 6, 1>& x) const {
  // sum_i c_i rho(r_i s) / s^2 + 1/2 sum_k h_k (lambda_k - 1)^2: the objective whose
  // stationary point the IRLS-weighted Gauss-Newton step solves for (rho pseudo-Huber, r_i
  // in model units, s pixels per model unit, c_i the row's prior weight).
  const double delta = options_.huber_delta_px;
  double cost = 0.0;
  for (int i = 0; i < n_rows; ++i) {
    const Row& row = rows_[i];
    if (row.prior_weight <= 0) continue;
    const double r = row.a0.head<3>().dot(x.head<3>()) +
                     depth_[row.window] * row.a0.tail<3>().dot(x.tail<3>()) - row.b;
    const double z = r * row.scale / delta;
    cost += row.prior_weight * delta * delta * (std::sqrt(1.0 + z * z) - 1.0) /
            (row.scale * row.scale);
  }
  const int n = static_cast<int>(windows.size());
  for (int k = 0; k < n; ++k) {
    const double d = depth_[k] - 1.0;
    cost += 0.5 * depth_prior_weight_ * windows[k].confidence * d * d;
  }
  return cost;
}

Eigen::Matrix<double, 6, 1> MotionFit::depthGaussNewton(std::span<const WindowMotion> windows,
                                                        int n_rows,
                                                        Eigen::Matrix<double, 6, 1> x,
                                                        double sigma, int& iterations) {
  using Mat6 = Eigen::Matrix<double, 6, 6>;
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  const int n = static_cast<int>(windows.size());
  // scratch_: [0, n) h_k, [n, 2n) g_lambda_k, [2n, 3n) lambda_k before the step,
  // [3n, 4n) the lambda_k step (rows_.size() = scratch_.size() >= 4 n).
  double* const h = scratch_.data();
  double* const g_lambda = h + n;
  double* const depth_before = h + 2 * n;
  double* const depth_step = h + 3 * n;

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
  constexpr int kMaxHalvings = 6;
  double total = 0.0;
  for (int k = 0; k < n; ++k) total += keep_[k] ? windows[k].confidence : 0.0;
  const auto gauge = [&](int k) {
    return keep_[k] && total > 0 ? windows[k].confidence / total : 0.0;
  };
  double cost = depthCost(windows, n_rows, x);
  for (int pass = 0; pass < options_.max_iterations; ++pass) {
    Mat6 N = Mat6::Zero();
    Vec6 gx = Vec6::Zero();
    for (int k = 0; k < n; ++k) {
      const double prior = depth_prior_weight_ * windows[k].confidence;
      depth_xl_[k].setZero();
      h[k] = prior;
      g_lambda[k] = prior * (1.0 - depth_[k]);
    }
    for (int i = 0; i < n_rows; ++i) {
      const Row& row = rows_[i];
      if (row.weight <= 0) continue;
      const int k = row.window;
      Eigen::Matrix<double, 1, 6> Jx = row.a0;
      Jx.tail<3>() *= depth_[k];
      const double Jl = row.a0.tail<3>().dot(x.tail<3>());
      const double r = row.b - Jx.dot(x);
      N.noalias() += row.weight * Jx.transpose() * Jx;
      gx.noalias() += row.weight * r * Jx.transpose();
      depth_xl_[k].noalias() += row.weight * Jl * Jx.transpose();
      h[k] += row.weight * Jl * Jl;
      g_lambda[k] += row.weight * Jl * r;
    }
    // Gauge: sum_k c_k lambda_k = 1 (c_k = gauge(k)), a hard constraint that keeps
    // tau = t / (mean scene distance). Eliminating lambda and the multiplier:
    // (N - B D^-1 B^T + v v^T / q) dx = g_x - B D^-1 g_l + v (c^T D^-1 g_l - e) / q,
    // v = B D^-1 c, q = c^T D^-1 c, e = 1 - c^T lambda.
    Mat6 S = N;
    Vec6 rhs = gx;
    Vec6 v = Vec6::Zero();
    double q = 0.0, cg = 0.0, e = 1.0;
    for (int k = 0; k < n; ++k) {
      const double c = gauge(k);
      S.noalias() -= depth_xl_[k] * depth_xl_[k].transpose() / h[k];
      rhs.noalias() -= depth_xl_[k] * (g_lambda[k] / h[k]);
      v.noalias() += depth_xl_[k] * (c / h[k]);
      q += c * c / h[k];
      cg += c * g_lambda[k] / h[k];
      e -= c * depth_[k];
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
      depth_before[k] = depth_[k];
      depth_step[k] = (g_lambda[k] - depth_xl_[k].dot(dx) - gauge(k) * mu) / h[k];
    }
    // Backtracking: the largest of 1, 1/2, 1/4, ... that does not raise the cost; none
    // (a minimum to rounding): stay and stop.
    const Vec6 x_before = x;
    double t = 1.0;
    bool lowered = false;
    for (int halving = 0; halving <= kMaxHalvings; ++halving, t *= 0.5) {
      x = x_before + t * dx;
      for (int k = 0; k < n; ++k)
        depth_[k] = std::clamp(depth_before[k] + t * depth_step[k], 0.25, 4.0);
      const double trial = depthCost(windows, n_rows, x);
      if (trial <= cost) {
        cost = trial;
        lowered = true;
        break;
      }
    }
    if (!lowered) {
      x = x_before;
      for (int k = 0; k < n; ++k) depth_[k] = depth_before[k];
    }
    ++iterations;
    for (int i = 0; i < n_rows; ++i) {
      Row& row = rows_[i];
      row.a.head<3>() = row.a0.head<3>();
      row.a.tail<3>() = depth_[row.window] * row.a0.tail<3>();
      const double r_px = (row.a.dot(x) - row.b) * row.scale / options_.huber_delta_px;
      row.weight = row.prior_weight / std::sqrt(1.0 + r_px * r_px);
    }
    if (!lowered) break;
    const double step_sigmas = t * std::sqrt(std::max(dx.dot(S * dx), 0.0)) / sigma;
    if (t * dx.norm() < options_.tolerance || step_sigmas < kNegligibleStep) break;
  }
  return x;
}

void MotionFit::computeLeverage(std::span<const WindowMotion> windows, int n_rows,
                                const Eigen::Matrix<double, 6, 1>& x) {
  for (int i = 0; i < n_rows; ++i) rows_[i].leverage = 0.0;
  if (!options_.per_window_depth || depth_prior_weight_ <= 0) return;
  const int n = static_cast<int>(windows.size());
  for (int k = 0; k < n; ++k) scratch_[k] = depth_prior_weight_ * windows[k].confidence;
  for (int i = 0; i < n_rows; ++i) {
    const double J = rows_[i].a0.tail<3>().dot(x.tail<3>());
    scratch_[rows_[i].window] += rows_[i].weight * J * J;
  }
  for (int i = 0; i < n_rows; ++i) {
    const double J = rows_[i].a0.tail<3>().dot(x.tail<3>());
    rows_[i].leverage = rows_[i].weight * J * J / scratch_[rows_[i].window];
  }
}

double MotionFit::standardizedResidualPx(int i, const Eigen::Matrix<double, 6, 1>& x) const {
  const Row& row = rows_[i];
  const double r_px = std::abs((row.a.dot(x) - row.b) * row.scale);
  return r_px / std::sqrt(std::max(1.0 - row.leverage, 0.05));
}

MotionEstimate MotionFit::fit(std::span<const WindowMotion> windows, double forward_column) {
  using Mat6 = Eigen::Matrix<double, 6, 6>;
  using Vec6 = Eigen::Matrix<double, 6, 1>;
  MotionEstimate est;
  est.windows_total = static_cast<int>(windows.size());
  est.windows_masked = static_cast<int>(
      std::count_if(windows.begin(), windows.end(), [](const WindowMotion& w) { return w.masked; }));
  if (windows.size() > keep_.size()) {
    est.status = FitStatus::kLost;  // workspace too small: configuration error upstream
    return est;
  }
  depth_prior_weight_ = 0.0;
  std::fill(depth_.begin(), depth_.end(), 1.0);  // inverseDepth() when depth is not fitted
  int n_rows = buildTranslationRows(windows, forward_column);
  if (n_rows < 2 * kMinWindows) return est;  // du and dv rows of too few windows: nothing to fit

  bool ok = false;
  Vec6 x = irls(n_rows, est.iterations, ok);
  if (!ok) return est;

  // In-window rotation and scale, weighted by their own noise relative to the shifts.
  if (options_.use_rotation_scale) {
    const double sigma_t = shiftSigma(x, n_rows);
    const int n_trans = n_rows;
    for (std::size_t k = 0; k < windows.size(); ++k) {
      if (!keep_[k] || windows[k].rs_confidence <= 0 || !(windows[k].scale > 0)) continue;
      const double theta = gamma_ * (windows[k].center_u - forward_column);
      const ModelRows m = modelRows(theta, kappa_);
      const double conf = windows[k].rs_confidence;
      const int w = static_cast<int>(k);
      rows_[n_rows++] =
          Row{m.rotation, m.rotation, windows[k].rotation, 1.0, conf, conf, kRotation, w};
      rows_[n_rows++] = Row{m.log_scale, m.log_scale, std::log(windows[k].scale), 1.0, conf,
                            conf, kLogScale, w};
    }
    if (n_rows > n_trans) {
      const double floor_rs = 1e-4;
      const double sigma_r = std::max(robustSigma(kRotation, x, n_rows), floor_rs);
      const double sigma_s = std::max(robustSigma(kLogScale, x, n_rows), floor_rs);
      for (int i = n_trans; i < n_rows; ++i) {
        Row& row = rows_[i];
        const double sigma = row.kind == kRotation ? sigma_r : sigma_s;
        // Residuals expressed in "equivalent shift pixels" for the loss, weights by 1/var.
        row.scale = sigma_t / sigma / gamma_;
        row.prior_weight *= (sigma_t / sigma) * (sigma_t / sigma);
        row.weight = row.prior_weight;
      }
      for (int i = 0; i < n_trans; ++i) rows_[i].weight = rows_[i].prior_weight;
      int more = 0;
      x = irls(n_rows, more, ok);
      est.iterations += more;
      if (!ok) return est;
    }
  }

  if (options_.per_window_depth) x = fitDepth(windows, n_rows, x, est.iterations);

  // Final least-squares pass on the inliers, judged by standardized residuals: a window's
  // inverse depth absorbs part of its rows' residuals (leverage w J^2 / h), which would
  // otherwise make the robust sigma too small and reject good windows.
  computeLeverage(windows, n_rows, x);
  int m = 0;
  for (int i = 0; i < n_rows; ++i) scratch_[m++] = standardizedResidualPx(i, x);
  const double sigma_px = kMadToSigma * medianOf(scratch_.data(), m);
  const double threshold = std::max(options_.inlier_sigmas * sigma_px, 0.1);
  Mat6 N = Mat6::Zero();
  Vec6 g = Vec6::Zero();
  int used_rows = 0;
  for (int i = 0; i < n_rows; ++i) {
    Row& row = rows_[i];
    row.weight = standardizedResidualPx(i, x) < threshold ? row.prior_weight : 0.0;
    if (row.weight <= 0) continue;
    N.noalias() += row.weight * row.a.transpose() * row.a;
    g.noalias() += row.weight * row.b * row.a.transpose();
    ++used_rows;
  }
  const Eigen::SelfAdjointEigenSolver<Mat6> eig(N, Eigen::EigenvaluesOnly);
  const double lmin = eig.eigenvalues()(0), lmax = eig.eigenvalues()(5);
  if (used_rows < 8 || !(lmin > 0) || lmax / lmin > options_.max_condition) return est;
  const Eigen::LDLT<Mat6> ldlt(N);
  x = ldlt.solve(g);
  if (!x.allFinite()) return est;

  // Residual statistics and covariance sigma^2 N^-1 (model units).
  double wrr = 0.0, shift_rr = 0.0;
  int shift_n = 0;
  for (int i = 0; i < n_rows; ++i) {
    const Row& row = rows_[i];
    if (row.weight <= 0) continue;
    const double r = row.a.dot(x) - row.b;
    wrr += row.weight * r * r;
    if (row.kind == kDu || row.kind == kDv) {
      shift_rr += (r * row.scale) * (r * row.scale);
      ++shift_n;
    }
  }
  // With per-window depth, lambda are nuisance parameters: the covariance of (omega, tau)
  // is the inverse of the Schur complement N - N_xl N_ll^-1 N_lx (N_ll diagonal: each row
  // has one lambda) under the gauge constraint, and each lambda uses up h/(h + prior)
  // degrees of freedom.
  Mat6 information = N;
  double depth_dof = 0.0;
  if (options_.per_window_depth && depth_prior_weight_ > 0) {
    const int n = static_cast<int>(windows.size());
    for (int k = 0; k < n; ++k) {
      depth_xl_[k].setZero();
      scratch_[k] = 0.0;
    }
    for (int i = 0; i < n_rows; ++i) {
      const Row& row = rows_[i];
      if (row.weight <= 0) continue;
      const double J = row.a0.tail<3>().dot(x.tail<3>());  // d(prediction)/d(lambda_k)
      depth_xl_[row.window].noalias() += row.weight * J * row.a.transpose();
      scratch_[row.window] += row.weight * J * J;
    }
    double total = 0.0, q = 0.0;
    for (int k = 0; k < n; ++k) total += keep_[k] ? windows[k].confidence : 0.0;
    Vec6 v = Vec6::Zero();
    for (int k = 0; k < n; ++k) {
      if (!keep_[k]) continue;
      const double h = scratch_[k], prior = depth_prior_weight_ * windows[k].confidence;
      information.noalias() -= depth_xl_[k] * depth_xl_[k].transpose() / (h + prior);
      depth_dof += h / (h + prior);
      const double c = windows[k].confidence / total;
      v.noalias() += depth_xl_[k] * (c / (h + prior));
      q += c * c / (h + prior);
    }
    if (q > 0) information.noalias() += v * v.transpose() / q;  // the gauge constraint
  }
  const double dof = std::max(used_rows - 6 - depth_dof, 1.0);
  const Eigen::LDLT<Mat6> marginal(information);
  est.covariance = (wrr / dof) * marginal.solve(Mat6::Identity());
  est.residual_rms_px = shift_n > 0 ? std::sqrt(shift_rr / shift_n) : 0.0;
  est.windows_used = (shift_n + 1) / 2;  // du and dv rows of a window count once
  est.omega = x.head<3>();
  est.tau = x.tail<3>();

  const bool few =
      est.windows_used < options_.min_window_fraction * (est.windows_total - est.windows_masked);
  est.status = (few || est.residual_rms_px > options_.max_residual_px) ? FitStatus::kDegraded
                                                                        : FitStatus::kOk;
  return est;
}

}  // namespace omnipose
