#include "omnipose/motion_model.hpp"

#include <cmath>

#include "omnipose/window_motion.hpp"

namespace omnipose {

double windowAttenuation(int window_px, double gamma) {
  // kappa = sum_x w(x) cos(gamma x) / sum_x w(x), w = the registration's taper over the
  // window's columns. Phase correlation weights each column by the taper of both windows,
  // so w = taper^2.
  double num = 0.0, den = 0.0;
  const double c = 0.5 * (window_px - 1);
  for (int i = 0; i < window_px; ++i) {
    const double taper = windowTaper(i, window_px);
    const double w = taper * taper;
    num += w * std::cos(gamma * (i - c));
    den += w;
  }
  return den > 0 ? num / den : 1.0;
}

ModelRows modelRows(double theta, double kappa) {
  const double s = std::sin(theta), c = std::cos(theta);
  ModelRows r;
  r.du << 0, 0, 1, -kappa * s, kappa * c, 0;
  r.dv << -kappa * s, kappa * c, 0, 0, 0, -1;
  r.rotation << kappa * c, kappa * s, 0, 0, 0, 0;
  r.log_scale << 0, 0, 0, -kappa * c, -kappa * s, 0;
  return r;
}

ModelMotion predictMotion(const Eigen::Matrix<double, 6, 1>& x, double theta, double kappa) {
  const ModelRows r = modelRows(theta, kappa);
  return {r.du.dot(x), r.dv.dot(x), r.rotation.dot(x), r.log_scale.dot(x)};
}

Eigen::Vector2d predictWindowShiftPx(const Eigen::Matrix<double, 6, 1>& x, double center_u,
                                     double forward_column, double gamma, double kappa) {
  const ModelMotion m = predictMotion(x, gamma * (center_u - forward_column), kappa);
  return Eigen::Vector2d(m.du_rad, m.dv_rad) / gamma;
}

}  // namespace omnipose
