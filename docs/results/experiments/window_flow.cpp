// What each window measures against the box room's exact geometry (docs/results/ANALYSIS.md,
// issue 27: the rectangle's heading drift).
//
// For every frame pair K-1 -> K of a box-room dataset rendered by omnipose-synth (the
// default room: 6 x 5 m, floor -1 m, ceiling +1.5 m), the windows are registered as the
// pipeline's first pass does it (WindowRegistration with the default pipeline options on the
// pipeline's panoramas) and compared with the exact flow: each window's taper-weighted mean
// du and dv over its pixels, and its exact horizontal and vertical expansions (ex, ey: the
// taper-weighted regression slopes of du on the column offset and of dv on the row offset).
// Each pair is then fitted (MotionFit, default options) three ways:
//   measured   the registered windows;
//   exact-uv   du and dv replaced by the exact means (the measured scale and rotation kept);
//   exact-all  du, dv replaced, the scale by exp((ex + ey) / 2) (the isotropic mix the fit's
//              model assumes, DESIGN.md section 3) and the in-window rotation by 0;
//   exact-phi  the measured windows with the in-window rotation replaced by the exact one
//              (the antisymmetric part of the exact flow's gradient, (d(du)/dv - d(dv)/du) / 2,
//              taper-weighted).
// Printed per pair: the yaw error of each fit (fitted omega_z minus the true one, mrad) and,
// over the windows, the RMS of ln(scale) - (ex + ey) / 2 and the ratio of the measured to the
// exact ln(scale) in the windows within 20 degrees of the direction of travel (forward or
// backward; pairs with translation only). The last lines sum the yaw errors over the pairs,
// in degrees (what each way would add to the chained heading), then the roll, pitch and yaw
// errors of each fit (camera frame, degrees; over a straight drive the camera frame does
// not turn, so these are what each way adds to the chained attitude), and give the least-squares
// fit ln(scale) ~ a ex + b ey over all valid windows of all pairs: how the log-polar
// correlation mixes the two expansions (the model assumes a = b = 1/2).
//
// --dewarp (slow: one registration of the whole panorama per window): each window of the
// current panorama is also de-warped about its centre by its exact expansions (ex, ey;
// bicubic) and registered again, so that what is left of its scale is what a perfectly
// predicted anisotropic de-warp would leave; printed: the RMS of that residual ln s, and the
// yaw error of one more fit, on the measured windows with ln s = (ex + ey) / 2 + the residual.
//
// Built with the project (target omnipose-experiment-window-flow); run from the repository
// root:
//   build/bin/omnipose-experiment-window-flow DATASET FIRST LAST [--windows | --dewarp]
//                                                [--scatter-only]
//     DATASET  a box-room dataset with groundtruth.tum (frames rendered without noise
//              show the model's error alone); FIRST..LAST: the current frames K of the pairs
//     --windows  also print every window of every pair
//     --dewarp   add the de-warped registration (see above)
//     --scatter-only  fit with MotionFit::Options::rotation_deformation 0: the in-window
//                rotation equations weighted by their scatter alone (the fit before 2026-11-28)

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "omnipose/io/dataset.hpp"
#include "omnipose/motion_fit.hpp"
#include "omnipose/pipeline.hpp"
#include "omnipose/so3.hpp"
#include "omnipose/synth/synth.hpp"
#include "omnipose/unwrapper.hpp"
#include "omnipose/window_registration.hpp"

namespace {

using namespace omnipose;

/// Exact motion of one window between the two frames (current -> previous panorama).
struct ExactWindow {
  double du = 0.0, dv = 0.0;  ///< taper-weighted mean shift, pixels
  double ex = 0.0, ey = 0.0;  ///< taper-weighted slopes d(du)/du and d(dv)/dv
  double phi = 0.0;           ///< in-window rotation: (d(du)/dv - d(dv)/du) / 2, radians
  /// ln s of the fit's model: the isotropic mix of the two expansions.
  double mix() const { return 0.5 * (ex + ey); }
};

ExactWindow exactWindow(const PanoramaGeometry& g, const synth::Scene& room,
                        const Eigen::Isometry3d& previous, const Eigen::Isometry3d& current,
                        double centre_u, int top, int length) {
  const Eigen::Isometry3d to_previous = previous.inverse();
  double sw = 0, su = 0, sv = 0, sxx = 0, sxu = 0, syy = 0, syv = 0, syu = 0, sxv = 0;
  const double half = 0.5 * (length - 1);
  for (int j = 0; j < length; ++j) {
    for (int i = 0; i < length; ++i) {
      const double u = centre_u - half + i, v = top + j;
      const Eigen::Vector3d ray = current.linear() * g.bearing(u, v);
      const Eigen::Vector3d point = room.textureDirection(current.translation(), ray);
      const Eigen::Vector3d q = to_previous * point;
      const double u_prev = g.column(std::atan2(q.y(), q.x()));
      const double v_prev = g.row(q.z() / std::hypot(q.x(), q.y()));
      const double du = std::remainder(u_prev - u, g.width);  // around the ring
      const double dv = v_prev - v;
      const double w = windowTaper(i, length) * windowTaper(j, length);
      const double x = i - half, y = j - half;
      sw += w, su += w * du, sv += w * dv;
      sxx += w * x * x, sxu += w * x * du, syy += w * y * y, syv += w * y * dv;
      syu += w * y * du, sxv += w * x * dv;
    }
  }
  // The map to the previous window is s [[1, phi], [-phi, 1]] (DESIGN.md section 3).
  return {su / sw, sv / sw, sxu / sxx, syv / syy, 0.5 * (syu / syy - sxv / sxx)};
}

/// `current` re-sampled about window centre (u_c, v_c) so that its expansion by
/// (exp(ln_x), exp(ln_y)) is undone (u wraps around the ring).
cv::Mat dewarp(const cv::Mat& current, double u_c, double v_c, double ln_x, double ln_y) {
  cv::Mat map_u(current.size(), CV_32F), map_v(current.size(), CV_32F);
  const int width = current.cols;
  for (int v = 0; v < current.rows; ++v) {
    for (int u = 0; u < width; ++u) {
      const double source = u_c + std::remainder(u - u_c, width) * std::exp(-ln_x);
      map_u.at<float>(v, u) = static_cast<float>(source - width * std::floor(source / width));
      map_v.at<float>(v, u) = static_cast<float>(v_c + (v - v_c) * std::exp(-ln_y));
    }
  }
  cv::Mat out;
  cv::remap(current, out, map_u, map_v, cv::INTER_CUBIC, cv::BORDER_WRAP);
  return out;
}

void usage() {
  std::fprintf(stderr, "usage: omnipose-experiment-window-flow DATASET FIRST LAST "
                       "[--windows | --dewarp] [--scatter-only]\n");
}

int run(int argc, char** argv) {
  bool print_windows = false, with_dewarp = false, scatter_only = false, flags_known = true;
  for (int i = 4; i < argc; ++i) {
    const std::string flag = argv[i];
    print_windows = print_windows || flag == "--windows";
    with_dewarp = with_dewarp || flag == "--dewarp";
    scatter_only = scatter_only || flag == "--scatter-only";
    flags_known =
        flags_known && (flag == "--windows" || flag == "--dewarp" || flag == "--scatter-only");
  }
  if (argc < 4 || !flags_known || (print_windows && with_dewarp)) {
    usage();
    return 2;
  }
  const Dataset dataset = Dataset::open(argv[1]);
  const int first = std::atoi(argv[2]), last = std::atoi(argv[3]);
  const int frames = static_cast<int>(dataset.frames.size());
  if (!dataset.groundtruth || first < 1 || last < first || last >= frames ||
      static_cast<int>(dataset.groundtruth->size()) != frames) {
    std::fprintf(stderr,
                 "%s: needs groundtruth.tum with a pose per frame and 1 <= FIRST <= LAST < %d\n",
                 argv[1], frames);
    return 2;
  }
  const auto& truth = *dataset.groundtruth;
  const PanoramaGeometry& g = dataset.calibration.panorama;
  synth::Scene room;
  room.kind = synth::SceneKind::kBox;

  PipelineOptions options;
  if (scatter_only) options.fit.rotation_deformation = 0.0;
  Pipeline pipeline(dataset.calibration, options);
  WindowRegistration registration(g.size(), options.registration);
  const int n = registration.windowCount(), length = options.registration.window;
  MotionFit fit(options.fit, g.gamma(), length, n);
  std::vector<WindowMotion> measured(n), exact_uv(n), exact_all(n), exact_phi(n), dewarped(n),
      again(n);
  std::vector<ExactWindow> exact(n);

  cv::Mat previous;
  const auto panoramaOf = [&](int k) {
    auto image = readFrame(dataset.frames[k].path,
                           inputFrameSize(dataset.calibration, options.unwrap.input));
    if (!image) {
      const std::string message(image.error().message());
      std::fprintf(stderr, "%s: %s\n", dataset.frames[k].path.c_str(), message.c_str());
      std::exit(1);
    }
    (void)pipeline.process(*image);
    return pipeline.lastPanorama().clone();
  };
  previous = panoramaOf(first - 1);

  std::printf("# pair  yaw error [mrad]: measured  exact-uv  exact-all  exact-phi  |  "
              "ln s - mix RMS  "
              "travel-direction ln s measured/exact%s\n",
              with_dewarp ? "  |  de-warped: residual ln s RMS, yaw error [mrad]" : "");
  double dewarped_yaw_sum = 0.0;
  Eigen::Vector3d attitude_sum[4] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(),
                                     Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  double sxx = 0, sxy = 0, syy = 0, sxl = 0, syl = 0;  // normal equations of ln s ~ a ex + b ey
  int regressed = 0;
  for (int k = first; k <= last; ++k) {
    const cv::Mat current = panoramaOf(k);
    registration.setReference(previous);
    registration.measure(current, measured);
    const Eigen::Isometry3d& pose_prev = truth[k - 1].pose;
    const Eigen::Isometry3d& pose_cur = truth[k].pose;
    const Eigen::Vector3d omega_true =
        rotationVector(pose_prev.linear().transpose() * pose_cur.linear());
    const Eigen::Vector3d t_cam = pose_prev.inverse() * pose_cur.translation();
    const double travel_theta = std::atan2(t_cam.y(), t_cam.x());
    double rr = 0.0, ratio = 0.0;
    int used = 0, travel = 0;
    for (int w = 0; w < n; ++w) {
      exact[w] = exactWindow(g, room, pose_prev, pose_cur, registration.windowCenter(w),
                             registration.windowTop(), length);
      exact_uv[w] = measured[w];
      exact_uv[w].du = exact[w].du;
      exact_uv[w].dv = exact[w].dv;
      exact_all[w] = exact_uv[w];
      const double mix = exact[w].mix();
      exact_all[w].scale = std::exp(mix);
      exact_all[w].rotation = 0.0;
      exact_phi[w] = measured[w];
      exact_phi[w].rotation = exact[w].phi;
      if (!measured[w].valid || measured[w].rs_confidence <= 0) continue;
      const double ln_s = std::log(measured[w].scale);
      rr += (ln_s - mix) * (ln_s - mix);
      const double ex = exact[w].ex, ey = exact[w].ey;
      sxx += ex * ex, sxy += ex * ey, syy += ey * ey, sxl += ex * ln_s, syl += ey * ln_s;
      ++regressed;
      ++used;
      // Within 20 degrees of the direction of travel, forward or backward.
      const double theta = g.azimuth(measured[w].center_u);
      if (omega_true.norm() < 1e-9 && t_cam.norm() > 0 &&
          std::abs(std::sin(theta - travel_theta)) < std::sin(20.0 * std::numbers::pi / 180) &&
          std::abs(mix) > 1e-6) {
        ratio += ln_s / mix;
        ++travel;
      }
    }
    double residual_rr = 0.0;
    int residuals = 0;
    if (with_dewarp) {
      dewarped = measured;
      const double v_c = registration.windowTop() + 0.5 * (length - 1);
      for (int w = 0; w < n; ++w) {
        if (!measured[w].valid || measured[w].rs_confidence <= 0) continue;
        registration.measure(dewarp(current, registration.windowCenter(w), v_c, exact[w].ex,
                                    exact[w].ey),
                             again);
        if (again[w].rs_confidence <= 0) continue;
        const double residual = std::log(again[w].scale);
        dewarped[w].scale = std::exp(exact[w].mix() + residual);
        residual_rr += residual * residual;
        ++residuals;
      }
    }
    double yaw[5] = {0, 0, 0, 0, 0};
    const std::vector<WindowMotion>* inputs[4] = {&measured, &exact_uv, &exact_all, &exact_phi};
    for (int i = 0; i < 4; ++i) {
      const MotionEstimate e = fit.fit(*inputs[i], g.forward_column);
      const Eigen::Vector3d error =
          e.status != FitStatus::kLost ? Eigen::Vector3d(e.omega - omega_true)
                                       : Eigen::Vector3d::Constant(std::nan(""));
      yaw[i] = error.z();
      attitude_sum[i] += error;
    }
    if (with_dewarp) {
      const MotionEstimate e = fit.fit(dewarped, g.forward_column);
      yaw[4] = e.status != FitStatus::kLost ? e.omega.z() - omega_true.z() : std::nan("");
      dewarped_yaw_sum += yaw[4];
    }
    std::printf("%5d  %+9.4f %+9.4f %+9.4f %+9.4f  |  %.5f  %s", k, yaw[0] * 1e3, yaw[1] * 1e3,
                yaw[2] * 1e3, yaw[3] * 1e3, used > 0 ? std::sqrt(rr / used) : std::nan(""),
                travel > 0 ? std::to_string(ratio / travel).c_str() : "-");
    if (with_dewarp)
      std::printf("  |  %.5f %+9.4f",
                  residuals > 0 ? std::sqrt(residual_rr / residuals) : std::nan(""), yaw[4] * 1e3);
    std::printf("\n");
    if (print_windows) {
      std::printf("#   k theta[deg] valid  du meas/exact [px]   dv meas/exact [px]   "
                  "ln s meas  ex  ey   phi meas/exact [rad]\n");
      for (int w = 0; w < n; ++w) {
        std::printf("  %3d %7.1f %d  %+8.4f %+8.4f  %+8.4f %+8.4f  %+8.5f %+8.5f %+8.5f  "
                    "%+8.5f %+8.5f\n",
                    w, g.azimuth(measured[w].center_u) * 180 / std::numbers::pi,
                    measured[w].valid, measured[w].du, exact[w].du, measured[w].dv, exact[w].dv,
                    std::log(measured[w].scale), exact[w].ex, exact[w].ey, measured[w].rotation,
                    exact[w].phi);
      }
    }
    previous = current;
  }
  const double to_deg = 180.0 / std::numbers::pi;
  std::printf("# sum over %d pairs [deg]: measured %+.3f  exact-uv %+.3f  exact-all %+.3f"
              "  exact-phi %+.3f",
              last - first + 1, attitude_sum[0].z() * to_deg, attitude_sum[1].z() * to_deg,
              attitude_sum[2].z() * to_deg, attitude_sum[3].z() * to_deg);
  if (with_dewarp) std::printf("  de-warped %+.3f", dewarped_yaw_sum * to_deg);
  std::printf("\n");
  const char* names[4] = {"measured", "exact-uv", "exact-all", "exact-phi"};
  for (int i = 0; i < 4; ++i)
    std::printf("# %-9s roll %+.3f  pitch %+.3f  yaw %+.3f deg (summed, camera frame)\n",
                names[i], attitude_sum[i].x() * to_deg, attitude_sum[i].y() * to_deg,
                attitude_sum[i].z() * to_deg);
  const double det = sxx * syy - sxy * sxy;
  // Only with expansions to speak of (RMS above 1e-4: translation) that are not proportional.
  constexpr double kMinExpansion = 1e-4;
  if (regressed > 0 && std::min(sxx, syy) > regressed * kMinExpansion * kMinExpansion &&
      det > 1e-6 * sxx * syy)
    std::printf("# ln s ~ %.3f ex + %.3f ey (least squares over the valid windows)\n",
                (sxl * syy - syl * sxy) / det, (syl * sxx - sxl * sxy) / det);
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(argc, argv);
  } catch (const std::exception& e) {  // a dataset that does not open, a bad calibration
    std::fprintf(stderr, "omnipose-experiment-window-flow: %s\n", e.what());
    return 1;
  }
}
