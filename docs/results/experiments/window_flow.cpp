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
// --energy: du and dv replaced by the exact flow's mean weighted, pixel by pixel, by the
// whitened window's squared derivative along the axis (the window's spectrum set to unit
// magnitude and weighted as the translation correlator weighs it); a model of how a phase
// correlation's peak weighs the texture. Printed: the yaw error of that fit ("energy"), and
// the RMS over the windows of the measured du and dv less each of the two exact means.
//
// --synthetic (slow: 4 registrations of the whole panorama per window): the previous
// panorama moved by the exact flow and registered against itself ("warp": every pixel's flow;
// bicubic in double precision on a grid 4 times finer, the panorama band-limited onto it), and
// per window by that flow's taper-weighted affine fit over the window ("affine"), by its
// similarity part alone ("similarity": shift, isotropic expansion, rotation, what the
// registration models), and by the similarity without its expansion ("rigid": the shift and
// the rotation, fitted with its scale set to the similarity's expansion; "rigid-uv": with du
// and dv exact as well). On the similarity's windows three more fits: du and dv replaced by
// the exact ones ("sim-uv"), the scale and rotation replaced ("sim-rs"), and the windows
// registered again with their exact rotation and expansion given (measure()'s
// known_rotation_scale: the de-rotation and de-scaling exact, the log-polar stage skipped;
// "sim-known"). Printed: the yaw error of each fit. Render less warp is the image's formation
// (the lens, the unwrapping, the renderer's sampling); warp less affine, the flow bending
// within a window; affine less similarity, the anisotropic expansion and the shear;
// similarity less rigid, the expansion; rigid less rigid-uv, a window that only moves.
//
// --preshift (slow): each window of the current panorama shifted along u, exactly (Fourier),
// by its exact mean du ("preshift") or by the fractional part of it ("fraction") before it
// is registered, the shift then added back: what a registration centred on a perfect
// prediction of the shift would read.
//
// Built with the project (target omnipose-experiment-window-flow); run from the repository
// root:
//   build/bin/omnipose-experiment-window-flow DATASET FIRST LAST
//       [--windows | --dewarp | --energy | --synthetic | --preshift] [--scatter-only]
//       [--cubic]
//     DATASET  a box-room dataset with groundtruth.tum (frames rendered without noise
//              show the model's error alone); FIRST..LAST: the current frames K of the pairs
//     --windows  also print every window of every pair
//     --dewarp, --energy, --synthetic, --preshift  add that comparison (see above); one
//                of them at a time, and --windows with none but --energy, --synthetic or
//                --preshift
//     --scatter-only  fit with MotionFit::Options::rotation_deformation 0: the in-window
//                rotation equations weighted by their scatter alone (the fit before 2026-11-28)
//     --cubic    de-warp the windows with the cubic sampler (WindowRegistration::Options::
//                cubic_sampling; daemon.yaml's pipeline.cubic_window_sampling)

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
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

double square(double x) { return x * x; }

/// Exact motion of one window between the two frames (current -> previous panorama).
struct ExactWindow {
  double du = 0.0, dv = 0.0;  ///< taper-weighted mean shift, pixels
  /// The mean shift weighted by the whitened window's gradient energy (--energy): what a
  /// phase correlation's peak would read if each pixel pulled it by its share of the
  /// whitened spectrum's energy along the axis. NaN without --energy.
  double du_energy = std::nan(""), dv_energy = std::nan("");
  double ex = 0.0, ey = 0.0;  ///< taper-weighted slopes d(du)/du and d(dv)/dv
  double phi = 0.0;           ///< in-window rotation: (d(du)/dv - d(dv)/du) / 2, radians
  /// ln s of the fit's model: the isotropic mix of the two expansions.
  double mix() const { return 0.5 * (ex + ey); }
};

ExactWindow exactWindow(const PanoramaGeometry& g, const synth::Scene& room,
                        const Eigen::Isometry3d& previous, const Eigen::Isometry3d& current,
                        double centre_u, int top, int length, const cv::Mat* energy_u = nullptr,
                        const cv::Mat* energy_v = nullptr) {
  const Eigen::Isometry3d to_previous = previous.inverse();
  double sw = 0, su = 0, sv = 0, sxx = 0, sxu = 0, syy = 0, syv = 0, syu = 0, sxv = 0;
  double seu = 0, sev = 0, seu_du = 0, sev_dv = 0;
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
      if (energy_u) {
        const double eu = energy_u->at<float>(j, i), ev = energy_v->at<float>(j, i);
        seu += eu, sev += ev, seu_du += eu * du, sev_dv += ev * dv;
      }
    }
  }
  // The map to the previous window is s [[1, phi], [-phi, 1]] (DESIGN.md section 3).
  ExactWindow exact;
  exact.du = su / sw, exact.dv = sv / sw, exact.ex = sxu / sxx, exact.ey = syv / syy;
  exact.phi = 0.5 * (syu / syy - sxv / sxx);
  if (energy_u) exact.du_energy = seu_du / seu, exact.dv_energy = sev_dv / sev;
  return exact;
}

/// The whitened window's gradient energy per pixel, along u and along v: the window of
/// `panorama` (columns centre_u - (length - 1) / 2 .., wrapping; rows top ..) times the
/// taper, its spectrum set to unit magnitude and weighted by the square root of the
/// translation correlator's Gaussian (sigma 1 px), then differentiated.
void whitenedEnergy(const cv::Mat& panorama, double centre_u, int top, int length,
                    cv::Mat& energy_u, cv::Mat& energy_v) {
  cv::Mat window(length, length, CV_32F);
  const int first = static_cast<int>(std::lround(centre_u - 0.5 * (length - 1)));
  for (int j = 0; j < length; ++j)
    for (int i = 0; i < length; ++i) {
      const int u = ((first + i) % panorama.cols + panorama.cols) % panorama.cols;
      window.at<float>(j, i) = static_cast<float>(panorama.at<float>(top + j, u) *
                                                  windowTaper(i, length) *
                                                  windowTaper(j, length));
    }
  cv::Mat spectrum;
  cv::dft(window, spectrum, cv::DFT_COMPLEX_OUTPUT);
  cv::Mat du_spectrum(spectrum.size(), CV_32FC2), dv_spectrum(spectrum.size(), CV_32FC2);
  constexpr double kSigma = 1.0;  // the translation correlator's (window_registration.cpp)
  for (int r = 0; r < length; ++r)
    for (int c = 0; c < length; ++c) {
      const cv::Vec2f z = spectrum.at<cv::Vec2f>(r, c);
      const double w0 = 2 * std::numbers::pi * (r < length / 2 ? r : r - length) / length;
      const double w1 = 2 * std::numbers::pi * (c < length / 2 ? c : c - length) / length;
      const double gain = std::exp(-0.25 * kSigma * kSigma * (w0 * w0 + w1 * w1)) /
                          std::max(std::hypot(static_cast<double>(z[0]), static_cast<double>(z[1])), 1e-12);
      // d/du multiplies by i w1, d/dv by i w0.
      du_spectrum.at<cv::Vec2f>(r, c) = cv::Vec2f(-z[1] * gain * w1, z[0] * gain * w1);
      dv_spectrum.at<cv::Vec2f>(r, c) = cv::Vec2f(-z[1] * gain * w0, z[0] * gain * w0);
    }
  cv::Mat gu, gv;
  cv::idft(du_spectrum, gu, cv::DFT_REAL_OUTPUT | cv::DFT_SCALE);
  cv::idft(dv_spectrum, gv, cv::DFT_REAL_OUTPUT | cv::DFT_SCALE);
  energy_u = gu.mul(gu);
  energy_v = gv.mul(gv);
}

/// The exact flow of every panorama pixel (current -> previous): flow_u, flow_v (CV_32F,
/// the panorama's size), so that current(u, v) shows what previous shows at
/// (u + flow_u, v + flow_v).
void exactFlowMap(const PanoramaGeometry& g, const synth::Scene& room,
                  const Eigen::Isometry3d& previous, const Eigen::Isometry3d& current,
                  cv::Mat& flow_u, cv::Mat& flow_v) {
  const Eigen::Isometry3d to_previous = previous.inverse();
  flow_u.create(g.height, g.width, CV_32F);
  flow_v.create(g.height, g.width, CV_32F);
  for (int v = 0; v < g.height; ++v)
    for (int u = 0; u < g.width; ++u) {
      const Eigen::Vector3d ray = current.linear() * g.bearing(u, v);
      const Eigen::Vector3d q = to_previous * room.textureDirection(current.translation(), ray);
      flow_u.at<float>(v, u) = static_cast<float>(
          std::remainder(g.column(std::atan2(q.y(), q.x())) - u, g.width));
      flow_v.at<float>(v, u) = static_cast<float>(g.row(q.z() / std::hypot(q.x(), q.y())) - v);
    }
}

/// How much finer upsampled() samples the panorama.
constexpr int kUpsample = 4;

/// `panorama` (H x W) band-limited onto a kUpsample times finer grid, with its rows mirrored
/// below it (2 kUpsample H x kUpsample W; row kUpsample v, column kUpsample u is pixel (u, v)):
/// zero-padding the spectrum of the ring and its mirror image, so the result is periodic in
/// both axes with no edge, so a bicubic warp on it adds little of its own.
cv::Mat upsampled(const cv::Mat& panorama) {
  const int h = panorama.rows, w = panorama.cols;
  cv::Mat mirrored;
  cv::vconcat(panorama, panorama, mirrored);
  cv::flip(panorama, mirrored.rowRange(h, 2 * h), 0);
  cv::Mat spectrum;
  cv::dft(mirrored, spectrum, cv::DFT_COMPLEX_OUTPUT);
  const int rows = 2 * h, big_rows = kUpsample * rows, big_cols = kUpsample * w;
  cv::Mat padded = cv::Mat::zeros(big_rows, big_cols, CV_32FC2);
  // Every frequency but the Nyquist row and column (left out: they have no sign).
  for (int r = 0; r < rows; ++r) {
    if (2 * r == rows) continue;
    const int big_r = r < rows / 2 ? r : r + big_rows - rows;
    for (int c = 0; c < w; ++c) {
      if (2 * c == w) continue;
      const int big_c = c < w / 2 ? c : c + big_cols - w;
      padded.at<cv::Vec2f>(big_r, big_c) = spectrum.at<cv::Vec2f>(r, c);
    }
  }
  cv::Mat out;
  cv::idft(padded, out, cv::DFT_REAL_OUTPUT | cv::DFT_SCALE);
  return out * static_cast<double>(kUpsample * kUpsample);
}

/// Keys' cubic convolution weights (a = -0.5) of the four samples around a point t in [0, 1)
/// past the second.
std::array<double, 4> cubicWeights(double t) {
  const auto near = [](double x) { return (1.5 * x - 2.5) * x * x + 1.0; };           // |x| < 1
  const auto far = [](double x) { return ((-0.5 * x + 2.5) * x - 4.0) * x + 2.0; };  // 1..2
  return {far(1.0 + t), near(t), near(1.0 - t), far(2.0 - t)};
}

/// The panorama whose upsampled() image is `fine`, moved by the flow (flow_u, flow_v):
/// out(u, v) = panorama(u + flow_u, v + flow_v), bicubic on the fine grid (periodic: around
/// the ring, and mirrored above and below), in double precision (cv::remap quantises its
/// coordinates to 1/32 of a sample, which moved every window's du by about 0.004 px).
cv::Mat warpByFlow(const cv::Mat& fine, const cv::Mat& flow_u, const cv::Mat& flow_v) {
  cv::Mat out(flow_u.size(), CV_32F);
  const int rows = fine.rows, cols = fine.cols, width = flow_u.cols;
  for (int v = 0; v < flow_u.rows; ++v)
    for (int u = 0; u < width; ++u) {
      const double x = kUpsample * (u + flow_u.at<float>(v, u));
      const double y = kUpsample * (v + flow_v.at<float>(v, u));
      const double x0 = std::floor(x), y0 = std::floor(y);
      const std::array<double, 4> wx = cubicWeights(x - x0), wy = cubicWeights(y - y0);
      double sum = 0.0;
      for (int j = 0; j < 4; ++j) {
        const int r = ((static_cast<int>(y0) - 1 + j) % rows + rows) % rows;
        const float* row = fine.ptr<float>(r);
        double line = 0.0;
        for (int i = 0; i < 4; ++i)
          line += wx[i] * row[((static_cast<int>(x0) - 1 + i) % cols + cols) % cols];
        sum += wy[j] * line;
      }
      out.at<float>(v, u) = static_cast<float>(sum);
    }
  return out;
}

/// The taper-weighted affine fit of the exact flow over window (centre_u, top, length),
/// extended over the whole panorama (u measured around the ring from centre_u): the flow
/// that window would see if the scene's flow were affine across it; kSimilarity: only its
/// similarity part (the mean shift, the isotropic expansion and the rotation: what the
/// registration models), without the anisotropic expansion and the shear; kRigid: the mean
/// shift and the rotation alone, without any expansion.
enum class FlowPart { kAffine, kSimilarity, kRigid };
void affineFlow(const cv::Mat& flow_u, const cv::Mat& flow_v, double centre_u, int top,
                int length, FlowPart part, cv::Mat& affine_u, cv::Mat& affine_v) {
  const int width = flow_u.cols;
  const double half = 0.5 * (length - 1), v_c = top + half;
  double sw = 0, su = 0, sv = 0, sxx = 0, syy = 0, sxu = 0, syu = 0, sxv = 0, syv = 0;
  for (int j = 0; j < length; ++j)
    for (int i = 0; i < length; ++i) {
      const int u = static_cast<int>(std::lround(centre_u - half)) + i;
      const double du = flow_u.at<float>(top + j, ((u % width) + width) % width);
      const double dv = flow_v.at<float>(top + j, ((u % width) + width) % width);
      const double w = windowTaper(i, length) * windowTaper(j, length);
      const double x = i - half, y = j - half;
      sw += w, su += w * du, sv += w * dv, sxx += w * x * x, syy += w * y * y;
      sxu += w * x * du, syu += w * y * du, sxv += w * x * dv, syv += w * y * dv;
    }
  double a = sxu / sxx, b = syu / syy, c = sxv / sxx, d = syv / syy;  // du/dx du/dy dv/dx dv/dy
  if (part != FlowPart::kAffine) {
    const double expansion = part == FlowPart::kSimilarity ? 0.5 * (a + d) : 0.0,
                 rotation = 0.5 * (b - c);
    a = d = expansion, b = rotation, c = -rotation;
  }
  affine_u.create(flow_u.size(), CV_32F);
  affine_v.create(flow_u.size(), CV_32F);
  for (int v = 0; v < flow_u.rows; ++v)
    for (int u = 0; u < width; ++u) {
      const double x = std::remainder(u - centre_u, width), y = v - v_c;
      affine_u.at<float>(v, u) = static_cast<float>(su / sw + a * x + b * y);
      affine_v.at<float>(v, u) = static_cast<float>(sv / sw + c * x + d * y);
    }
}

/// `panorama` shifted along u by `shift` pixels, exactly (each row's spectrum times a phase
/// ramp; u is periodic): out(u, v) = panorama(u - shift, v).
cv::Mat shiftAlongU(const cv::Mat& panorama, double shift) {
  cv::Mat spectrum;
  cv::dft(panorama, spectrum, cv::DFT_ROWS | cv::DFT_COMPLEX_OUTPUT);
  const int width = panorama.cols;
  for (int c = 0; c < width; ++c) {
    const int k = c <= width / 2 ? c : c - width;
    const double phase = -2.0 * std::numbers::pi * k * shift / width;
    const bool nyquist = 2 * c == width;  // real: its ramp's real part alone
    const std::complex<float> z(static_cast<float>(std::cos(phase)),
                                static_cast<float>(nyquist ? 0.0 : std::sin(phase)));
    for (int r = 0; r < panorama.rows; ++r) {
      auto& bin = spectrum.at<cv::Vec2f>(r, c);
      const std::complex<float> value = std::complex<float>(bin[0], bin[1]) * z;
      bin = cv::Vec2f(value.real(), value.imag());
    }
  }
  cv::Mat out;
  cv::idft(spectrum, out, cv::DFT_ROWS | cv::DFT_REAL_OUTPUT | cv::DFT_SCALE);
  return out;
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
                       "[--windows | --dewarp | --energy | --synthetic | --preshift] [--scatter-only] "
                       "[--cubic]\n");
}

int run(int argc, char** argv) {
  bool print_windows = false, with_dewarp = false, scatter_only = false, with_energy = false,
       with_synthetic = false, with_preshift = false, cubic = false, flags_known = true;
  for (int i = 4; i < argc; ++i) {
    const std::string flag = argv[i];
    print_windows = print_windows || flag == "--windows";
    with_dewarp = with_dewarp || flag == "--dewarp";
    scatter_only = scatter_only || flag == "--scatter-only";
    with_energy = with_energy || flag == "--energy";
    with_synthetic = with_synthetic || flag == "--synthetic";
    with_preshift = with_preshift || flag == "--preshift";
    cubic = cubic || flag == "--cubic";
    flags_known = flags_known && (flag == "--windows" || flag == "--dewarp" ||
                                  flag == "--scatter-only" || flag == "--energy" ||
                                  flag == "--synthetic" || flag == "--preshift" ||
                                  flag == "--cubic");
  }
  const int comparisons = int{with_dewarp} + int{with_energy} + int{with_synthetic} +
                          int{with_preshift};  // one at a time
  if (argc < 4 || !flags_known || comparisons > 1 || (print_windows && with_dewarp)) {
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
  options.registration.cubic_sampling = cubic;
  Pipeline pipeline(dataset.calibration, options);
  WindowRegistration registration(g.size(), options.registration);
  const int n = registration.windowCount(), length = options.registration.window;
  MotionFit fit(options.fit, g.gamma(), length, n);
  std::vector<WindowMotion> measured(n), exact_uv(n), exact_all(n), exact_phi(n), dewarped(n),
      again(n), exact_energy(n);
  cv::Mat energy_u, energy_v;
  // --energy: over all valid windows of all pairs, the squared differences of the measured
  // du, dv from the taper-weighted and from the energy-weighted exact means.
  double taper_du2 = 0, taper_dv2 = 0, energy_du2 = 0, energy_dv2 = 0, energy_yaw_sum = 0;
  long energy_windows = 0;
  // --synthetic: the previous panorama warped by the exact flow (every pixel's), and per
  // window by that flow's affine fit over the window; their registrations, fits and errors.
  std::vector<WindowMotion> warped_exact(n), warped_affine(n), warped_similarity(n),
      similarity_uv(n), similarity_rs(n), similarity_known(n), known_rs(n), warped_rigid(n),
      rigid_uv(n), scratch(n);
  // --preshift: the windows registered after the shift, and after its fractional part; the
  // sums above serve it (warp_*: the whole shift, affine_*: the fraction).
  std::vector<WindowMotion> preshifted(n), preshifted_fraction(n);
  cv::Mat flow_u, flow_v, affine_u, affine_v;
  double warp_du2 = 0, affine_du2 = 0, warp_yaw_sum = 0, affine_yaw_sum = 0;
  double similarity_yaw_sums[4] = {0, 0, 0, 0}, rigid_yaw_sums[2] = {};
  long synthetic_windows = 0;
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
    // The yaw error of the default fit on `windows`, rad (NaN when the fit is lost).
    const auto yawError = [&](const std::vector<WindowMotion>& windows) {
      const MotionEstimate e = fit.fit(windows, g.forward_column);
      return e.status != FitStatus::kLost ? e.omega.z() - omega_true.z() : std::nan("");
    };
    double rr = 0.0, ratio = 0.0;
    int used = 0, travel = 0;
    for (int w = 0; w < n; ++w) {
      if (with_energy)
        whitenedEnergy(current, registration.windowCenter(w), registration.windowTop(), length,
                       energy_u, energy_v);
      exact[w] = exactWindow(g, room, pose_prev, pose_cur, registration.windowCenter(w),
                             registration.windowTop(), length, with_energy ? &energy_u : nullptr,
                             with_energy ? &energy_v : nullptr);
      exact_energy[w] = measured[w];
      if (with_energy) {
        exact_energy[w].du = exact[w].du_energy;
        exact_energy[w].dv = exact[w].dv_energy;
        if (measured[w].valid) {
          taper_du2 += square(measured[w].du - exact[w].du);
          taper_dv2 += square(measured[w].dv - exact[w].dv);
          energy_du2 += square(measured[w].du - exact[w].du_energy);
          energy_dv2 += square(measured[w].dv - exact[w].dv_energy);
          ++energy_windows;
        }
      }
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
    double synthetic_yaw[8] = {};
    if (with_preshift) {
      // Each window of the current panorama shifted along u by its exact mean du before it
      // is registered (the residual plus that shift), and by the fractional part of it.
      for (int w = 0; w < n; ++w) {
        const double whole = exact[w].du, fraction = whole - std::round(whole);
        for (int variant = 0; variant < 2; ++variant) {
          const double shift = variant == 0 ? whole : fraction;
          registration.measure(shiftAlongU(current, shift), scratch, false);
          WindowMotion& out = variant == 0 ? preshifted[w] : preshifted_fraction[w];
          out = scratch[w];
          out.du += shift;
        }
        if (!measured[w].valid || !preshifted[w].valid || !preshifted_fraction[w].valid)
          continue;
        warp_du2 += square(preshifted[w].du - exact[w].du);
        affine_du2 += square(preshifted_fraction[w].du - exact[w].du);
        ++synthetic_windows;
      }
      synthetic_yaw[0] = yawError(preshifted);
      synthetic_yaw[1] = yawError(preshifted_fraction);
      warp_yaw_sum += synthetic_yaw[0];
      affine_yaw_sum += synthetic_yaw[1];
    }
    if (with_synthetic) {
      exactFlowMap(g, room, pose_prev, pose_cur, flow_u, flow_v);
      const cv::Mat fine = upsampled(previous);
      registration.measure(warpByFlow(fine, flow_u, flow_v), warped_exact, false);
      for (int w = 0; w < n; ++w) {
        for (const FlowPart part : {FlowPart::kAffine, FlowPart::kSimilarity, FlowPart::kRigid}) {
          affineFlow(flow_u, flow_v, registration.windowCenter(w), registration.windowTop(),
                     length, part, affine_u, affine_v);
          const cv::Mat warped = warpByFlow(fine, affine_u, affine_v);
          registration.measure(warped, scratch, false);
          (part == FlowPart::kAffine       ? warped_affine
           : part == FlowPart::kSimilarity ? warped_similarity
                                           : warped_rigid)[w] = scratch[w];
          if (part != FlowPart::kSimilarity) continue;
          // Registered again, de-rotated and de-scaled by the similarity's own rotation and
          // expansion instead of the log-polar stage's.
          known_rs[w].rotation = exact[w].phi;
          known_rs[w].scale = std::exp(exact[w].mix());
          known_rs[w].rs_confidence = 1.0;
          registration.measure(warped, scratch, false, known_rs);
          similarity_known[w] = scratch[w];
        }
        // The similarity's own shift, and its own expansion and rotation, are exact[w]'s.
        similarity_uv[w] = similarity_rs[w] = warped_similarity[w];
        similarity_uv[w].du = exact[w].du;
        similarity_uv[w].dv = exact[w].dv;
        similarity_rs[w].scale = std::exp(exact[w].mix());
        similarity_rs[w].rotation = exact[w].phi;
        // The rigid part's windows with the similarity's scale (what the fit expects of the
        // translation), and that with the exact du and dv as well.
        warped_rigid[w].scale = std::exp(exact[w].mix());
        rigid_uv[w] = warped_rigid[w];
        rigid_uv[w].du = exact[w].du;
        rigid_uv[w].dv = exact[w].dv;
        if (!measured[w].valid || !warped_exact[w].valid || !warped_affine[w].valid) continue;
        warp_du2 += square(warped_exact[w].du - exact[w].du);
        affine_du2 += square(warped_affine[w].du - exact[w].du);
        ++synthetic_windows;
      }
      const std::vector<WindowMotion>* warps[8] = {
          &warped_exact,  &warped_affine,    &warped_similarity, &similarity_uv,
          &similarity_rs, &similarity_known, &warped_rigid,      &rigid_uv};
      for (int i = 0; i < 8; ++i) synthetic_yaw[i] = yawError(*warps[i]);
      warp_yaw_sum += synthetic_yaw[0];
      affine_yaw_sum += synthetic_yaw[1];
      for (int i = 0; i < 4; ++i) similarity_yaw_sums[i] += synthetic_yaw[2 + i];
      for (int i = 0; i < 2; ++i) rigid_yaw_sums[i] += synthetic_yaw[6 + i];
    }
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
    if (with_energy) {
      yaw[4] = yawError(exact_energy);
      energy_yaw_sum += yaw[4];
    }
    if (with_dewarp) {
      yaw[4] = yawError(dewarped);
      dewarped_yaw_sum += yaw[4];
    }
    std::printf("%5d  %+9.4f %+9.4f %+9.4f %+9.4f  |  %.5f  %s", k, yaw[0] * 1e3, yaw[1] * 1e3,
                yaw[2] * 1e3, yaw[3] * 1e3, used > 0 ? std::sqrt(rr / used) : std::nan(""),
                travel > 0 ? std::to_string(ratio / travel).c_str() : "-");
    if (with_energy) std::printf("  |  energy %+9.4f", yaw[4] * 1e3);
    if (with_synthetic)
      std::printf("  |  warp %+9.4f affine %+9.4f similarity %+9.4f sim-uv %+9.4f sim-rs %+9.4f"
                  " sim-known %+9.4f rigid %+9.4f rigid-uv %+9.4f",
                  synthetic_yaw[0] * 1e3, synthetic_yaw[1] * 1e3, synthetic_yaw[2] * 1e3,
                  synthetic_yaw[3] * 1e3, synthetic_yaw[4] * 1e3, synthetic_yaw[5] * 1e3,
                  synthetic_yaw[6] * 1e3, synthetic_yaw[7] * 1e3);
    if (with_preshift)
      std::printf("  |  preshift %+9.4f fraction %+9.4f", synthetic_yaw[0] * 1e3,
                  synthetic_yaw[1] * 1e3);
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
  if (with_energy) std::printf("  exact-energy %+.3f", energy_yaw_sum * to_deg);
  if (with_synthetic)
    std::printf("  warp %+.3f  affine %+.3f  similarity %+.3f", warp_yaw_sum * to_deg,
                affine_yaw_sum * to_deg, similarity_yaw_sums[0] * to_deg);
  if (with_synthetic)
    std::printf("  sim-uv %+.3f  sim-rs %+.3f  sim-known %+.3f", similarity_yaw_sums[1] * to_deg,
                similarity_yaw_sums[2] * to_deg, similarity_yaw_sums[3] * to_deg);
  if (with_synthetic)
    std::printf("  rigid %+.3f  rigid-uv %+.3f", rigid_yaw_sums[0] * to_deg,
                rigid_yaw_sums[1] * to_deg);
  if (with_preshift)
    std::printf("  preshift %+.3f  fraction %+.3f", warp_yaw_sum * to_deg,
                affine_yaw_sum * to_deg);
  std::printf("\n");
  if (with_energy && energy_windows > 0)
    std::printf("# measured - exact RMS over %ld windows [px]: taper-weighted du %.5f dv %.5f"
                "  energy-weighted du %.5f dv %.5f\n",
                energy_windows, std::sqrt(taper_du2 / energy_windows),
                std::sqrt(taper_dv2 / energy_windows), std::sqrt(energy_du2 / energy_windows),
                std::sqrt(energy_dv2 / energy_windows));
  if (with_preshift && synthetic_windows > 0)
    std::printf("# registered - exact mean du RMS over %ld windows [px]: pre-shifted by the "
                "exact mean du %.5f, by its fraction %.5f\n",
                synthetic_windows, std::sqrt(warp_du2 / synthetic_windows),
                std::sqrt(affine_du2 / synthetic_windows));
  if (with_synthetic && synthetic_windows > 0)
    std::printf("# registered - exact mean du RMS over %ld windows [px]: warped by the exact "
                "flow %.5f, by its affine fit per window %.5f\n",
                synthetic_windows, std::sqrt(warp_du2 / synthetic_windows),
                std::sqrt(affine_du2 / synthetic_windows));
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
