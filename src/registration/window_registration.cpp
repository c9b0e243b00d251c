#include "omnipose/window_registration.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <complex>
#include <cstring>
#include <limits>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "common/problem_list.hpp"
#include "image/cubic_kernel.hpp"
#include "registration/column_spectra.hpp"
#include "registration/log_polar.hpp"
#include "registration/noise_estimate.hpp"
#include "registration/phase_correlator.hpp"
#include "registration/shared_pool_registration.hpp"
#include "runtime/fft_plan.hpp"
#include "runtime/simd.hpp"
#include "runtime/worker_pool.hpp"

// Per window (DESIGN.md section 4; Buelow & Birk, iFMI):
//   1. cut the L x L window (wrapping around u), remove its taper-weighted mean, apply a
//      separable Hann taper, zero-pad to n x n, r2c FFT -> F_c (windows without a static
//      mask: the v-direction half of that FFT is done once per panorama for all of them,
//      column_spectra.hpp);
//   2. log-polar resample H |F_c| (high-pass H), r2c FFT -> L_c; phase-correlate with the
//      reference's L_p inside the rotation/scale prior -> (phi, s);
//   3. when (phi, s) moves the window corners noticeably, resample the current window from
//      the panorama de-rotated and de-scaled about its centre, taper, FFT -> F_d (else F_c);
//   4. phase-correlate F_d with the reference's F_p -> (du, dv), confidence.
// F_c and L_c are whitened once and kept as the next frame's reference.
//
// Rotation/scale sign. With x_p = s R x_c, R = [[cos phi, sin phi], [-sin phi, cos phi]]
// (u right, v down), P(x) = C(R^T x / s), so F_P(k) = s^2 F_C(s R^T k). R^T rotates the
// frequency angle alpha = atan2(k_v, k_u) by +phi, hence
//   |F_P|(ln rho, alpha) = s^2 |F_C|(ln rho + ln s, alpha + phi):
// content at (ln rho, alpha) in the current log-polar image appears at
// (ln rho - ln s, alpha - phi) in the reference one, and the correlation peaks at
// (-phi, -ln s) (rows = alpha, columns = ln rho).

namespace omnipose {
namespace reg = registration;

namespace {

/// Internal tuning of the iFMI stages, chosen on real texture (tests/registration).
struct Tuning {
  /// Width (std) of the translation correlation peak, pixels. The Gaussian spectral weight
  /// keeps frequencies up to ~3 / sigma rad/px and sets the correlation surface size.
  double translation_sigma_px = 1.0;
  // Wider peaks (smaller surfaces, also for the first pass only) cost accuracy beyond the
  // 5 % allowed: docs/PERFORMANCE.md, "Tried and not taken".
  /// Log-polar grid: angles over [0, pi) and log-spaced radii. Smaller grids cost accuracy
  /// beyond the 5 % allowed (docs/PERFORMANCE.md).
  int log_polar_angles = 96;
  int log_polar_radii = 64;
  /// Radii of the log-polar ring, fractions of the FFT's Nyquist radius n/2.
  double log_polar_r_min = 0.06;
  double log_polar_r_max = 0.9;
  /// Width (std) of the log-polar correlation peak, log-polar samples.
  double log_polar_sigma = 1.0;
  /// Translation stage: de-rotate/de-scale the current window only when the measured
  /// rotation/scale moves the window corners by more than this, pixels. Raising it skips
  /// the re-sampling and its FFT for more refinement windows, but 0.25 and 0.5 px cost
  /// accuracy beyond the 5 % allowed (docs/PERFORMANCE.md).
  double derotate_min_px = 0.1;
};

constexpr Tuning kTuning{};

/// WindowRegistration::minDewarp() for windows of `window` px.
double minDewarpFor(int window) {
  return kTuning.derotate_min_px / (std::numbers::sqrt2 * 0.5 * window);
}

/// A window is textureless when its taper-weighted standard deviation is at most this
/// fraction of its mean brightness plus kTextureFloorAbs (grey levels): only rounding noise
/// is left, and its phase carries no information.
/// Static masks (setValidity): usable pixels within kMaskMarginPx of a masked one are faded
/// out too (the in-window de-rotation moves window corners by a few pixels), with a
/// Gaussian fade of kMaskFeatherPx, so a mask border is never a sharp, static edge.
constexpr int kMaskMarginPx = 3;
constexpr double kMaskFeatherPx = 2.0;
constexpr double kTextureFloorRel = 1e-4;
constexpr double kTextureFloorAbs = 1e-6;

/// Static masks: a window whose feathered usable map is at least this everywhere has the
/// plain separable taper (the feathering's Gaussian leaves ~1e-7 below 1 on usable ground).
constexpr float kFullyUsable = 1.0f - 1e-5f;

/// Texture test of a tapered window: sum of squares `energy` over taper weights whose
/// squares sum to `weight2`, taper-weighted mean `mean`. False for NaN.
bool isTextured(double energy, double weight2, double mean) {
  return std::sqrt(energy / weight2) > kTextureFloorRel * std::abs(mean) + kTextureFloorAbs;
}

/// The registration's taper (windowTaper(), window_motion.hpp) as floats.
std::vector<float> taperTable(int length) {
  std::vector<float> taper(length);
  for (int j = 0; j < length; ++j) taper[j] = static_cast<float>(windowTaper(j, length));
  return taper;
}

/// sum_j a[j] b[j] (four lanes, so no serial chain of additions).
OMNIPOSE_SIMD_CLONES
float dot(const float* a, const float* b, int count) {
  runtime::simd::F4 acc = runtime::simd::broadcast(0.0f);
  int j = 0;
  for (; j + 4 <= count; j += 4) acc += runtime::simd::load(a + j) * runtime::simd::load(b + j);
  float tail = 0.0f;
  for (; j < count; ++j) tail += a[j] * b[j];
  return runtime::simd::sum(acc) + tail;
}

/// out[j] = h * taper[j] * (in[j] - mean) for j < count; returns sum_j out[j]^2. `out` may
/// be `in` (in place).
OMNIPOSE_SIMD_CLONES
float taperRow(float* out, const float* in, const float* taper, float h, float mean, int count) {
  namespace simd = runtime::simd;
  const simd::F4 h4 = simd::broadcast(h), m4 = simd::broadcast(mean);
  simd::F4 energy = simd::broadcast(0.0f);
  int j = 0;
  for (; j + 4 <= count; j += 4) {
    const simd::F4 x = h4 * simd::load(taper + j) * (simd::load(in + j) - m4);
    simd::store(out + j, x);
    energy += x * x;
  }
  float tail = 0.0f;
  for (; j < count; ++j) {
    out[j] = h * taper[j] * (in[j] - mean);
    tail += out[j] * out[j];
  }
  return simd::sum(energy) + tail;
}

/// A width no column reaches: the wrapped samplers below without a wrap (the vector samplers'
/// last count % 4 pixels).
constexpr int kNoWrap = std::numeric_limits<int>::max() / 2;

/// One row of an affine resampling with bilinear interpolation: out[j] = image(u0 + j du,
/// v0 + j dv), with u >= 0 and v clamped to [0, max_v] (both neighbours inside the image).
/// Columns wrap modulo `width` (the panorama is periodic in u).
OMNIPOSE_SIMD_CLONES
void sampleRowBilinearWrapped(const float* image, std::size_t stride, int width, float u0,
                              float du, float v0, float dv, float max_v, float* out, int count) {
  for (int j = 0; j < count; ++j) {
    const float u = u0 + static_cast<float>(j) * du;
    const float v = std::min(std::max(v0 + static_cast<float>(j) * dv, 0.0f), max_v);
    const int iu = static_cast<int>(u), iv = static_cast<int>(v);
    const float fu = u - static_cast<float>(iu), fv = v - static_cast<float>(iv);
    int c0 = iu;
    while (c0 >= width) c0 -= width;  // u < 2 W except for panoramas barely wider than L
    const int c1 = c0 + 1 == width ? 0 : c0 + 1;
    const float* r0 = image + static_cast<std::size_t>(iv) * stride;
    const float* r1 = r0 + stride;
    const float a = r0[c0] + fu * (r0[c1] - r0[c0]);
    const float b = r1[c0] + fu * (r1[c1] - r1[c0]);
    out[j] = a + fv * (b - a);
  }
}

/// As sampleRowBilinearWrapped() for a row whose columns stay inside the image (no wrap), four
/// pixels at a time.
OMNIPOSE_SIMD_CLONES
void sampleRowBilinear(const float* image, std::size_t stride, float u0, float du, float v0,
                       float dv, float max_v, float* out, int count) {
  namespace simd = runtime::simd;
  const simd::F4 lane{0.0f, 1.0f, 2.0f, 3.0f};
  const simd::F4 zero = simd::broadcast(0.0f), top = simd::broadcast(max_v);
  int j = 0;
  for (; j + 4 <= count; j += 4) {
    const simd::F4 x = simd::broadcast(static_cast<float>(j)) + lane;
    const simd::F4 u = simd::broadcast(u0) + x * du;
    const simd::F4 v = simd::min(simd::max(simd::broadcast(v0) + x * dv, zero), top);
    const simd::I4 iu = __builtin_convertvector(u, simd::I4);  // truncation = floor (>= 0)
    const simd::I4 iv = __builtin_convertvector(v, simd::I4);
    const simd::F4 fu = u - __builtin_convertvector(iu, simd::F4);
    const simd::F4 fv = v - __builtin_convertvector(iv, simd::F4);
    // Gather the 2 x 2 neighbourhoods (built from registers, not lane by lane in memory).
    const float* p0 = image + static_cast<std::size_t>(iv[0]) * stride + iu[0];
    const float* p1 = image + static_cast<std::size_t>(iv[1]) * stride + iu[1];
    const float* p2 = image + static_cast<std::size_t>(iv[2]) * stride + iu[2];
    const float* p3 = image + static_cast<std::size_t>(iv[3]) * stride + iu[3];
    const simd::F4 p00{p0[0], p1[0], p2[0], p3[0]};
    const simd::F4 p01{p0[1], p1[1], p2[1], p3[1]};
    const simd::F4 p10{p0[stride], p1[stride], p2[stride], p3[stride]};
    const simd::F4 p11{p0[stride + 1], p1[stride + 1], p2[stride + 1], p3[stride + 1]};
    const simd::F4 a = p00 + fu * (p01 - p00);
    const simd::F4 b = p10 + fu * (p11 - p10);
    simd::store(out + j, a + fv * (b - a));
  }
  if (j < count) {  // the last count % 4 pixels
    sampleRowBilinearWrapped(image, stride, kNoWrap, u0 + static_cast<float>(j) * du, du,
                             v0 + static_cast<float>(j) * dv, dv, max_v, out + j, count - j);
  }
}

/// One row of an affine resampling with Keys cubic interpolation (image/cubic_kernel.hpp):
/// out[j] = image(u0 + j du, v0 + j dv) for j < count, with u >= 1 (the left taps inside the
/// image). Rows beyond [0, height) replicate the edge rows; columns wrap modulo `width` (the
/// panorama is periodic in u; u < 2 width).
void sampleRowCubicWrapped(const float* image, std::size_t stride, int width, int height,
                           float u0, float du, float v0, float dv, float* out, int count) {
  const float v_lo = -2.0f, v_hi = static_cast<float>(height);
  for (int j = 0; j < count; ++j) {
    const float u = u0 + static_cast<float>(j) * du;
    const float v = std::clamp(v0 + static_cast<float>(j) * dv, v_lo, v_hi);
    const int iu = static_cast<int>(u), iv = static_cast<int>(std::floor(v));
    runtime::simd::F4 w[4];  // lane 0: the column taps' weights, lane 1: the rows'
    image::keysCubicWeights(
        runtime::simd::F4{u - static_cast<float>(iu), v - static_cast<float>(iv), 0.0f, 0.0f}, w);
    int c[4];
    c[0] = iu - 1;
    while (c[0] >= width) c[0] -= width;
    for (int t = 1; t < 4; ++t) c[t] = c[t - 1] + 1 == width ? 0 : c[t - 1] + 1;
    float sum = 0.0f;
    for (int r = 0; r < 4; ++r) {
      const int row = std::clamp(iv - 1 + r, 0, height - 1);
      const float* p = image + static_cast<std::size_t>(row) * stride;
      sum += w[r][1] * ((p[c[0]] * w[0][0] + p[c[1]] * w[1][0]) +
                        (p[c[2]] * w[2][0] + p[c[3]] * w[3][0]));
    }
    out[j] = sum;
  }
}

/// As sampleRowCubicWrapped() for a row whose taps stay inside the image's columns (no wrap),
/// four pixels at a time: per pixel the 4 x 4 taps are four row vectors weighted by the row
/// weights, then (the four pixels' sums transposed) by the column weights.
OMNIPOSE_SIMD_CLONES
void sampleRowCubic(const float* image, std::size_t stride, int height, float u0, float du,
                    float v0, float dv, float* out, int count) {
  namespace simd = runtime::simd;
  const simd::F4 lane{0.0f, 1.0f, 2.0f, 3.0f};
  const simd::F4 v_lo = simd::broadcast(-2.0f), v_hi = simd::broadcast(static_cast<float>(height));
  const simd::I4 row_lo{0, 0, 0, 0}, row_hi{height - 1, height - 1, height - 1, height - 1};
  int j = 0;
  for (; j + 4 <= count; j += 4) {
    const simd::F4 x = simd::broadcast(static_cast<float>(j)) + lane;
    const simd::F4 u = simd::broadcast(u0) + x * du;
    const simd::F4 v = simd::min(simd::max(simd::broadcast(v0) + x * dv, v_lo), v_hi);
    const simd::I4 iu = __builtin_convertvector(u, simd::I4);  // truncation = floor (u >= 1)
    const simd::I4 iv = simd::floorToInt(v);
    simd::F4 wu[4], wv[4];
    image::keysCubicWeights(u - __builtin_convertvector(iu, simd::F4), wu);
    image::keysCubicWeights(v - __builtin_convertvector(iv, simd::F4), wv);
    simd::I4 rows[4];  // the taps' rows, edge replicated
    for (int r = 0; r < 4; ++r) {
      const simd::I4 row = iv + (r - 1);
      rows[r] = row < row_lo ? row_lo : (row > row_hi ? row_hi : row);
    }
    const auto taps = [&]<int l>() {
      const float* p = image + (iu[l] - 1);
      return simd::splat<l>(wv[0]) * simd::load(p + rows[0][l] * stride) +
             simd::splat<l>(wv[1]) * simd::load(p + rows[1][l] * stride) +
             simd::splat<l>(wv[2]) * simd::load(p + rows[2][l] * stride) +
             simd::splat<l>(wv[3]) * simd::load(p + rows[3][l] * stride);
    };
    simd::F4 acc[4] = {taps.template operator()<0>(), taps.template operator()<1>(),
                       taps.template operator()<2>(), taps.template operator()<3>()};
    simd::transpose(acc[0], acc[1], acc[2], acc[3]);
    simd::store(out + j, (acc[0] * wu[0] + acc[1] * wu[1]) + (acc[2] * wu[2] + acc[3] * wu[3]));
  }
  if (j < count) {  // the last count % 4 pixels
    sampleRowCubicWrapped(image, stride, kNoWrap, height, u0 + static_cast<float>(j) * du, du,
                          v0 + static_cast<float>(j) * dv, dv, out + j, count - j);
  }
}

}  // namespace

std::vector<std::string> WindowRegistration::Options::validate() const {
  std::vector<std::string> p;
  detail::checkRange(p, "window", window, 16, kMaxWindow, " pixels");
  detail::checkRange(p, "step", step, 1, kMaxStep, " pixels");
  if (max_rotation_rad >= std::numbers::pi / 4)  // open at both ends
    p.push_back("max_rotation_rad: " + std::to_string(max_rotation_rad) +
                " must be below pi/4 (a quarter turn is ambiguous)");
  else
    detail::checkRange(p, "max_rotation_rad", max_rotation_rad, 0.0, std::numbers::pi / 4,
                       " radians", true);
  detail::checkRange(p, "max_log_scale", max_log_scale, 0.0, 0.5, "", true);
  detail::checkRange(p, "min_confidence", min_confidence, 0.0, 1.0);
  detail::checkRange(p, "min_usable_fraction", min_usable_fraction, 0.0, 1.0);
  return p;
}

std::vector<std::string> WindowRegistration::validate(cv::Size panorama, const Options& options) {
  std::vector<std::string> problems = options.validate();
  const std::string size = std::to_string(panorama.width) + " x " + std::to_string(panorama.height);
  if (panorama.width < 16 || panorama.height < 16) {
    problems.push_back("panorama: " + size + " pixels, both sides must be >= 16");
    return problems;
  }
  if (options.window > panorama.height || options.window > panorama.width)
    problems.push_back("window: " + std::to_string(options.window) +
                       " is larger than the panorama (" + size + ")");
  if (options.step >= 1 && options.window >= 1) {
    const long long windows = (static_cast<long long>(panorama.width) + options.step - 1) /
                              options.step;
    const long long samples = windows * options.window * options.window;
    if (samples > kMaxWindowSamples)
      problems.push_back("step: " + std::to_string(options.step) + " gives " +
                         std::to_string(windows) + " windows of " +
                         std::to_string(options.window) + " x " +
                         std::to_string(options.window) + " over the " +
                         std::to_string(panorama.width) + "-pixel panorama: " +
                         std::to_string(samples) + " window samples, the largest supported is " +
                         std::to_string(kMaxWindowSamples) + " (use a larger step or window)");
  }
  return problems;
}

/// Whitened spectra of every window of one frame: what the next frame is registered against.
struct WindowSpectra {
  runtime::FftwArray<runtime::Complex> translation;  ///< translation bands, window after window
  runtime::FftwArray<runtime::Complex> log_polar;    ///< log-polar bands, window after window
  std::vector<unsigned char> textured;       ///< per window: has usable texture
  std::vector<reg::PhaseNoise> translation_noise;  ///< per window: whiten()'s phase noise

  WindowSpectra(int windows, std::size_t translation_band, std::size_t log_polar_band)
      : translation(windows * translation_band),
        log_polar(windows * log_polar_band),
        textured(windows, 0),
        translation_noise(windows) {}
};

/// Result of preparing one window for the FFT.
struct TaperedWindow {
  bool textured = false;
  double energy = 0.0;  ///< sum of the squared tapered samples
};

/// What one worker thread owns: its FFTW plans and every buffer it writes while it
/// registers a window. Built once; nothing is shared between workers but read-only state.
struct Worker {
  /// max_rotation_rad: the rotation search's reach (Options), so that the log-polar
  /// correlation computes only the surface rows it searches.
  Worker(int fft_size, double max_rotation_rad, runtime::PlanEffort effort);

  // Window stage: tapered window (n x n, zero padding) -> half spectrum; or the window's
  // second stage from the panorama's column spectra.
  runtime::FftwArray<float> window;
  runtime::FftwArray<runtime::Complex> spectrum;
  runtime::FftPlan window_fft;
  reg::WindowSpectrum from_columns;
  reg::PhaseCorrelator translation;

  // Log-polar stage: H |F| -> log-polar image -> half spectrum.
  reg::LogPolarMap log_polar_map;
  runtime::FftwArray<float> log_polar;
  runtime::FftwArray<runtime::Complex> log_polar_spectrum;
  runtime::FftPlan log_polar_fft;
  reg::PhaseCorrelator rotation_scale;

  // One window's bands when the current frame is not kept, and the de-rotated band.
  runtime::FftwArray<runtime::Complex> scratch_translation, scratch_log_polar, derotated;
};

Worker::Worker(int fft_size, double max_rotation_rad, runtime::PlanEffort effort)
    : window(static_cast<std::size_t>(fft_size) * fft_size),
      spectrum(static_cast<std::size_t>(fft_size) * (fft_size / 2 + 1)),
      window_fft(runtime::FftPlan::realToComplex(fft_size, fft_size, window.data(), spectrum.data(),
                                             effort)),
      from_columns(fft_size, effort),
      translation(fft_size, fft_size, kTuning.translation_sigma_px, kTuning.translation_sigma_px,
                  effort, std::numeric_limits<double>::infinity(),
                  WindowRegistration::kExpectedDvReachPx),
      log_polar_map(fft_size, kTuning.log_polar_angles, kTuning.log_polar_radii,
                    kTuning.log_polar_r_min * fft_size / 2,
                    std::min(kTuning.log_polar_r_max * fft_size / 2, fft_size / 2 - 3.0)),
      log_polar(static_cast<std::size_t>(kTuning.log_polar_angles) * kTuning.log_polar_radii),
      log_polar_spectrum(static_cast<std::size_t>(kTuning.log_polar_angles) *
                         (kTuning.log_polar_radii / 2 + 1)),
      log_polar_fft(runtime::FftPlan::realToComplex(kTuning.log_polar_angles, kTuning.log_polar_radii,
                                                log_polar.data(), log_polar_spectrum.data(),
                                                effort)),
      rotation_scale(kTuning.log_polar_angles, kTuning.log_polar_radii, kTuning.log_polar_sigma,
                     kTuning.log_polar_sigma, effort, max_rotation_rad / log_polar_map.angleStep()),
      scratch_translation(translation.bandSize()),
      scratch_log_polar(rotation_scale.bandSize()),
      derotated(translation.bandSize()) {
  // FFTW_MEASURE planning wrote into the arrays; the zero padding must be zero.
  window.clear();
  log_polar.clear();
}

struct WindowRegistration::Impl {
  /// On `shared_pool`, or (nullptr) on a pool of its own of `threads` workers (0 = all cores).
  Impl(cv::Size panorama, const Options& o, runtime::WorkerPool* shared_pool, int threads,
       runtime::PlanEffort effort);

  Options options;
  int width, height;  ///< panorama size, pixels
  int windows;    ///< windowCount()
  int top;        ///< first panorama row of every window
  int fft_size;   ///< n >= L: windows are zero-padded to n x n
  double half;    ///< (L - 1) / 2: window centre offset from its first row/column

  std::vector<float> taper;  ///< Hann, length L
  double taper_weight;       ///< sum over the window of h_i h_j
  double taper_weight2;      ///< sum over the window of (h_i h_j)^2

  std::unique_ptr<runtime::WorkerPool> own_pool;  ///< when no pool is shared
  runtime::WorkerPool* pool;
  std::vector<std::unique_ptr<Worker>> workers;  ///< one per pool worker
  std::size_t translation_band, log_polar_band;  ///< band sizes (the same for every worker)
  int band_cols = 0;  ///< columns of a translation band (its rows: band_size / band_cols)
  /// setMotionBlur(): per window, the phases K / |K| of the blur kernel of the frame
  /// whitened next at the band's columns (band_cols each); blur_active[k] = 0: none.
  std::vector<runtime::Complex> blur_kernel;
  std::vector<unsigned char> blur_active;
  /// Multiplies the translation band of window k (just whitened from the frame whose blur
  /// setMotionBlur() gave) by conj(K / |K|), row by row: the blur kernel's phase taken out.
  void removeBlur(int k, runtime::Complex* band) const;
  double angle_step, log_step;                   ///< log-polar grid steps

  // Static mask (setValidity): per window, the taper times the feathered usable map,
  // L x L each, window after window; empty = the plain separable taper everywhere.
  std::vector<float> masked_taper;
  std::vector<double> masked_weight, masked_weight2;  ///< per window: sum w, sum w^2
  std::vector<unsigned char> mostly_masked;           ///< per window: not measured
  std::vector<unsigned char> window_masked;  ///< per window: has masked_taper weights (else plain)

  // Shared first stage of the window FFTs of the unmasked windows (column_spectra.hpp).
  std::unique_ptr<reg::ColumnSpectra> columns;

  // The panorama's noise (Options::noise_weighting): the estimator over the windows' rows
  // (usable pixels only; null without noise weighting), and the variance of the frame whose
  // bands are being whitened (0 without noise weighting or when it could not be measured).
  std::unique_ptr<reg::NoiseEstimator> noise_estimator;
  double noise_sigma = std::numeric_limits<double>::quiet_NaN();
  double noise_variance = 0.0;

  // Reference (previous frame) and candidate next reference; advance() swaps them.
  std::unique_ptr<WindowSpectra> reference, next;
  bool has_reference = false;
  bool next_ready = false;
  // Keyframe slots (reserveKeyframes): copies of earlier references.
  std::vector<std::unique_ptr<WindowSpectra>> keyframes;
  std::vector<unsigned char> keyframe_stored;
  /// Slot whose keyframe is still the reference itself (no copy is made: the reference's
  /// spectra move into the slot when the reference is replaced); -1 for none.
  int pending_keyframe = -1;

  /// The spectra of keyframe `slot` (the reference while it is the pending keyframe).
  const WindowSpectra& keyframe(int slot) const {
    return slot == pending_keyframe ? *reference : *keyframes[static_cast<std::size_t>(slot)];
  }
  /// Moves the reference into the pending keyframe's slot (a pointer swap); the reference
  /// then points to spectra about to be overwritten.
  void keepPendingKeyframe() {
    if (pending_keyframe < 0) return;
    std::swap(keyframes[static_cast<std::size_t>(pending_keyframe)], reference);
    pending_keyframe = -1;
  }

  double windowCenter(int k) const;
  bool mostlyMasked(int k) const { return !mostly_masked.empty() && mostly_masked[k]; }
  bool windowMasked(int k) const { return !window_masked.empty() && window_masked[k]; }
  int firstColumn(int k) const {
    return static_cast<int>((static_cast<long>(k) * options.step) % width);
  }
  /// The column stage of `panorama` on the pool (when some window uses it).
  void transformColumns(const cv::Mat& panorama);
  /// The whitened translation bands and log-polar bands of every window of `panorama` into
  /// `ref` (the noise measured last whitens them); `blurred`: `panorama` is the frame whose
  /// blur setMotionBlur() gave (removeBlur()).
  void transformInto(const cv::Mat& panorama, WindowSpectra& ref, bool blurred);
  void setValidity(const cv::Mat& validity);
  bool acceptsImage(const cv::Mat& panorama) const;
  TaperedWindow loadWindow(Worker& w, const cv::Mat& panorama, int k) const;
  TaperedWindow loadWarpedWindow(Worker& w, const cv::Mat& panorama, int k, double rotation,
                                 double scale) const;
  /// The rows of window k to taper into w.window: row i at first + i * stride (the
  /// panorama itself, or w.window after a copy or a re-sampling).
  struct WindowRows {
    const float* first;
    std::size_t stride;
  };
  WindowRows bufferRows(const Worker& w) const {
    return {w.window.data(), static_cast<std::size_t>(fft_size)};
  }
  TaperedWindow taperWindow(Worker& w, int k, WindowRows rows) const;
  TaperedWindow taperMaskedWindow(Worker& w, int k, WindowRows rows) const;
  /// F_c of window k from the column spectra (transformColumns() of this panorama done).
  TaperedWindow transformFromColumns(Worker& w, int k) const;
  TaperedWindow transformWindow(Worker& w, const cv::Mat& panorama, int k,
                                runtime::Complex* log_polar_band) const;
  /// Pixel noise energy per spectral bin of window k for unit pixel noise variance: the
  /// sum of its squared taper weights.
  double noiseEnergy(int k) const { return windowMasked(k) ? masked_weight2[k] : taper_weight2; }
  /// whiten()'s noise_power for window k of the frame being whitened.
  double noisePower(int k) const { return noise_variance * noiseEnergy(k); }
  /// Measures the noise of `panorama`, the frame whose bands are whitened next.
  void measureNoise(const cv::Mat& panorama);
  /// Registers window k of the current frame (F_c in w.spectrum) against `ref`; the current
  /// whitened bands when already made (else nullptr) with their phase noise.
  void measureWindow(Worker& w, const cv::Mat& panorama, int k, const TaperedWindow& cur,
                     const runtime::Complex* cur_translation, reg::PhaseNoise cur_translation_noise,
                     const runtime::Complex* cur_log_polar,
                     const WindowMotion* known, double expected_dv, const WindowMotion* dewarp,
                     const WindowSpectra& ref, WindowMotion& out) const;
};

WindowRegistration::Impl::Impl(cv::Size panorama, const Options& o,
                                runtime::WorkerPool* shared_pool, int threads,
                                runtime::PlanEffort effort)
    : options(o),
      width(panorama.width),
      height(panorama.height),
      windows((panorama.width + o.step - 1) / o.step),
      top((panorama.height - o.window) / 2),
      fft_size(reg::fastFftSize(o.window)),
      half(0.5 * (o.window - 1)),
      taper(taperTable(o.window)),
      own_pool(shared_pool != nullptr
                   ? nullptr
                   : std::make_unique<runtime::WorkerPool>(
                         threads > 0 ? threads : runtime::WorkerPool::onlineCores())),
      pool(shared_pool != nullptr ? shared_pool : own_pool.get()) {
  workers.reserve(pool->size());
  for (int i = 0; i < pool->size(); ++i)
    workers.push_back(std::make_unique<Worker>(fft_size, o.max_rotation_rad, effort));
  translation_band = workers[0]->translation.bandSize();
  band_cols = workers[0]->translation.surfaceCols() / 2 + 1;
  blur_kernel.resize(static_cast<std::size_t>(windows) * band_cols);
  blur_active.assign(static_cast<std::size_t>(windows), 0);
  log_polar_band = workers[0]->rotation_scale.bandSize();
  angle_step = workers[0]->log_polar_map.angleStep();
  log_step = workers[0]->log_polar_map.logRadiusStep();
  reference = std::make_unique<WindowSpectra>(windows, translation_band, log_polar_band);
  next = std::make_unique<WindowSpectra>(windows, translation_band, log_polar_band);
  double sum = 0.0, sum2 = 0.0;
  for (float h : taper) {
    sum += h;
    sum2 += static_cast<double>(h) * h;
  }
  taper_weight = sum * sum;
  taper_weight2 = sum2 * sum2;
  columns = std::make_unique<reg::ColumnSpectra>(width, fft_size, taper, effort);
  if (o.noise_weighting)
    noise_estimator = std::make_unique<reg::NoiseEstimator>(width, top, o.window);
}

void WindowRegistration::Impl::measureNoise(const cv::Mat& panorama) {
  if (!options.noise_weighting) return;
  noise_sigma = noise_estimator->sigma(panorama);
  noise_variance = std::isfinite(noise_sigma) ? noise_sigma * noise_sigma : 0.0;
}

void WindowRegistration::Impl::transformColumns(const cv::Mat& panorama) {
  if (std::count(window_masked.begin(), window_masked.end(), 1) == windows) return;
  const float* first_row = panorama.ptr<float>(top);
  const std::size_t stride = panorama.step1();
  auto task = [&](int, int chunk) { columns->transformChunk(first_row, stride, chunk); };
  pool->run(columns->chunks(), task);
}

TaperedWindow WindowRegistration::Impl::transformFromColumns(Worker& w, int k) const {
  const reg::WindowSpectrum::Stats stats =
      w.from_columns.transform(*columns, firstColumn(k), w.spectrum.data());
  TaperedWindow out;
  out.energy = stats.energy;
  out.textured = isTextured(stats.energy, taper_weight2, stats.mean);
  return out;
}

double WindowRegistration::Impl::windowCenter(int k) const {
  return std::fmod(k * static_cast<double>(options.step) + half, width);
}

bool WindowRegistration::Impl::acceptsImage(const cv::Mat& panorama) const {
  return panorama.type() == CV_32FC1 && panorama.cols == width &&
         panorama.rows == height;
}

TaperedWindow WindowRegistration::Impl::loadWindow(Worker& w, const cv::Mat& panorama,
                                                   int k) const {
  // Window k covers columns k*step .. k*step + L - 1, wrapping around u.
  const int length = options.window;
  const int first_col = firstColumn(k);
  const int head = std::min(length, width - first_col);
  // Not wrapping: tapered straight from the panorama's rows, without a copy.
  if (head == length)
    return taperWindow(w, k, {panorama.ptr<float>(top) + first_col, panorama.step1()});
  for (int i = 0; i < length; ++i) {
    const float* src = panorama.ptr<float>(top + i);
    float* dst = w.window.data() + static_cast<std::size_t>(i) * fft_size;
    std::memcpy(dst, src + first_col, sizeof(float) * head);
    std::memcpy(dst + head, src, sizeof(float) * (length - head));
  }
  return taperWindow(w, k, bufferRows(w));
}

TaperedWindow WindowRegistration::Impl::loadWarpedWindow(Worker& w, const cv::Mat& panorama,
                                                         int k, double rotation,
                                                         double scale) const {
  // D(y) = C(c + (s R)^-1 y), y about the window centre c: content of D at y appears at
  // y + (du, dv) in the reference window. (s R)^-1 = (1/s) [[cos, -sin], [sin, cos]].
  const int length = options.window;
  const double m00 = std::cos(rotation) / scale, m10 = std::sin(rotation) / scale;
  const double m01 = -m10, m11 = m00;
  // Columns are addressed from `base`, whole columns left of every sample (two for the
  // cubic's left tap), so coordinates stay small and positive (float keeps ~1e-5 px); rows
  // beyond the panorama replicate its edge rows.
  const bool cubic = options.cubic_sampling;
  const double centre_u = k * static_cast<double>(options.step) + half;  // may exceed W
  const double reach = half * (std::abs(m00) + std::abs(m01)) + (cubic ? 2.0 : 1.0);
  const double base = std::floor(centre_u - reach);
  const bool wraps = base < 0.0 || centre_u + reach + 1.0 >= width;
  const double wrapped_base = base - width * std::floor(base / width);  // in [0, W)
  const float* origin = panorama.ptr<float>(0) + (wraps ? 0 : static_cast<std::ptrdiff_t>(base));
  const std::size_t stride = panorama.step1();
  const double u_centre = centre_u - base + (wraps ? wrapped_base : 0.0);
  const double v_centre = top + half;
  const float max_v = static_cast<float>(height - 1) - 1e-3f;  // bilinear: both rows inside
  for (int i = 0; i < length; ++i) {
    // Row i starts at y = (-half, i - half).
    const double yv = i - half;
    const float u0 = static_cast<float>(u_centre - m00 * half + m01 * yv);
    const float v0 = static_cast<float>(v_centre - m10 * half + m11 * yv);
    const auto du = static_cast<float>(m00), dv = static_cast<float>(m10);
    float* dst = w.window.data() + static_cast<std::size_t>(i) * fft_size;
    if (cubic && wraps)
      sampleRowCubicWrapped(origin, stride, width, height, u0, du, v0, dv, dst, length);
    else if (cubic)
      sampleRowCubic(origin, stride, height, u0, du, v0, dv, dst, length);
    else if (wraps)
      sampleRowBilinearWrapped(origin, stride, width, u0, du, v0, dv, max_v, dst, length);
    else
      sampleRowBilinear(origin, stride, u0, du, v0, dv, max_v, dst, length);
  }
  return taperWindow(w, k, bufferRows(w));
}

void WindowRegistration::Impl::setValidity(const cv::Mat& validity) {
  if (options.noise_weighting)
    noise_estimator =
        std::make_unique<reg::NoiseEstimator>(width, top, options.window, validity);
  masked_taper.clear();
  masked_weight.clear();
  masked_weight2.clear();
  mostly_masked.assign(windows, 0);
  window_masked.assign(windows, 0);
  const int length = options.window;
  double minimum = 1.0;
  cv::minMaxLoc(validity, &minimum);
  if (minimum >= 1.0) return;  // nothing masked: the plain taper
  // Fade masked pixels out smoothly: erode the usable map by kMaskMarginPx, feather it with
  // a Gaussian of kMaskFeatherPx (periodic in u), and never let it exceed the original map,
  // so the fade lies entirely on usable pixels.
  cv::Mat usable, padded, faded;
  cv::threshold(validity, usable, 0.999, 1.0, cv::THRESH_BINARY);
  const int pad = static_cast<int>(std::ceil(kMaskMarginPx + 4 * kMaskFeatherPx)) + 1;
  cv::copyMakeBorder(usable, padded, 0, 0, pad, pad, cv::BORDER_WRAP);
  cv::erode(padded, padded, cv::getStructuringElement(cv::MORPH_ELLIPSE,
                                                      {2 * kMaskMarginPx + 1, 2 * kMaskMarginPx + 1}),
            {-1, -1}, 1, cv::BORDER_REPLICATE);
  cv::GaussianBlur(padded, faded, {0, 0}, kMaskFeatherPx, kMaskFeatherPx, cv::BORDER_REPLICATE);
  faded = cv::min(faded(cv::Rect(pad, 0, width, height)), usable);
  masked_taper.resize(static_cast<std::size_t>(windows) * length * length);
  masked_weight.assign(windows, 0.0);
  masked_weight2.assign(windows, 0.0);
  for (int k = 0; k < windows; ++k) {
    const int first_col = firstColumn(k);
    float* wk = masked_taper.data() + static_cast<std::size_t>(k) * length * length;
    double usable_weight = 0.0;
    float least = 1.0f;
    for (int i = 0; i < length; ++i) {
      const float* m = faded.ptr<float>(top + i);
      for (int j = 0; j < length; ++j) {
        const float usable_here = m[(first_col + j) % width];
        const float v = taper[i] * taper[j] * usable_here;
        wk[i * length + j] = v;
        usable_weight += v;
        masked_weight2[k] += static_cast<double>(v) * v;
        least = std::min(least, usable_here);
      }
    }
    window_masked[k] = least < kFullyUsable;
    masked_weight[k] = usable_weight;
    mostly_masked[k] = usable_weight < options.min_usable_fraction * taper_weight;
  }
}

TaperedWindow WindowRegistration::Impl::taperMaskedWindow(Worker& w, int k, WindowRows rows) const {
  // As taperWindow() with the window's own weights w_ij = h_i h_j m_ij (m: the feathered
  // usable map): mean m = sum w x / sum w, x <- w (x - m); masked pixels become 0.
  const int length = options.window;
  const float* wk = masked_taper.data() + static_cast<std::size_t>(k) * length * length;
  double weighted = 0.0;
  for (int i = 0; i < length; ++i)
    weighted +=
        dot(wk + static_cast<std::size_t>(i) * length, rows.first + i * rows.stride, length);
  const double mean = weighted / masked_weight[k];
  double energy = 0.0;
  for (int i = 0; i < length; ++i) {
    float* row = w.window.data() + static_cast<std::size_t>(i) * fft_size;
    energy += taperRow(row, rows.first + i * rows.stride,
                       wk + static_cast<std::size_t>(i) * length, 1.0f, static_cast<float>(mean),
                       length);
  }
  TaperedWindow out;
  out.energy = energy;
  out.textured = isTextured(energy, masked_weight2[k], mean);
  return out;
}

TaperedWindow WindowRegistration::Impl::taperWindow(Worker& w, int k, WindowRows rows) const {
  if (mostlyMasked(k)) return {};  // not measured
  if (windowMasked(k)) return taperMaskedWindow(w, k, rows);
  // Taper-weighted mean m = sum_ij h_i h_j x_ij / sum_ij h_i h_j: the tapered window has no DC.
  const int length = options.window;
  double weighted = 0.0;
  for (int i = 0; i < length; ++i)
    weighted += taper[i] * dot(taper.data(), rows.first + i * rows.stride, length);
  const double mean = weighted / taper_weight;
  // x <- h_i h_j (x - m); texture = taper-weighted standard deviation.
  double energy = 0.0;
  for (int i = 0; i < length; ++i) {
    float* row = w.window.data() + static_cast<std::size_t>(i) * fft_size;
    energy += taperRow(row, rows.first + i * rows.stride, taper.data(), taper[i],
                       static_cast<float>(mean), length);
  }
  TaperedWindow out;
  out.energy = energy;
  out.textured = isTextured(energy, taper_weight2, mean);  // false for NaN: never used
  return out;
}

TaperedWindow WindowRegistration::Impl::transformWindow(Worker& w, const cv::Mat& panorama, int k,
                                                        runtime::Complex* log_polar_band) const {
  if (mostlyMasked(k)) return {};  // not measured, no FFT
  // Step 1: F_c of the tapered window (left in `spectrum`).
  TaperedWindow tw;
  if (windowMasked(k)) {
    tw = loadWindow(w, panorama, k);
    w.window_fft.execute();
  } else {
    tw = transformFromColumns(w, k);
  }
  if (options.estimate_rotation_scale && tw.textured && log_polar_band != nullptr) {
    // Step 2 (iFMI): the high-passed |F_c| in log-polar coordinates, then its own spectrum.
    const double energy = w.log_polar_map.resample(w.spectrum.data(), w.log_polar.data());
    w.log_polar_fft.execute();
    w.rotation_scale.whiten(w.log_polar_spectrum.data(), energy, log_polar_band, false);
  }
  return tw;
}

void WindowRegistration::Impl::measureWindow(Worker& w, const cv::Mat& panorama, int k,
                                             const TaperedWindow& cur,
                                             const runtime::Complex* cur_translation,
                                             reg::PhaseNoise cur_translation_noise,
                                             const runtime::Complex* cur_log_polar,
                                             const WindowMotion* known, double expected_dv,
                                             const WindowMotion* dewarp,
                                             const WindowSpectra& ref, WindowMotion& out) const {
  out = WindowMotion{};
  out.center_u = windowCenter(k);
  out.masked = mostlyMasked(k);
  if (!cur.textured || !ref.textured[k]) return;

  // Step 2: rotation and scale, log-polar phase correlation searched only inside the prior
  // (no 180-degree ambiguity); the peak is at (-phi, -ln s) (see the top of this file).
  // Known values (the refinement pass) replace the search.
  double rotation = 0.0, scale = 1.0;
  if (known != nullptr) {
    if (known->rs_confidence > 0.0 && known->scale > 0.0) {
      rotation = known->rotation;
      scale = known->scale;
      out.rs_confidence = known->rs_confidence;
    }
  } else if (options.estimate_rotation_scale) {
    const reg::CorrelationPeak rs = w.rotation_scale.correlate(
        ref.log_polar.data() + k * log_polar_band, cur_log_polar,
        options.max_rotation_rad / angle_step, options.max_log_scale / log_step);
    if (!rs.on_border && rs.confidence >= options.min_confidence && rs.confidence > 0.0) {
      rotation = -rs.shift0 * angle_step;
      scale = std::exp(-rs.shift1 * log_step);
      out.rs_confidence = rs.confidence;
    }
  }
  out.rotation = rotation;
  out.scale = scale;
  // A given de-warp (measure()'s `dewarp`) replaces the window's own for step 3 only.
  if (dewarp != nullptr && std::isfinite(dewarp->rotation) && dewarp->scale > 0.0 &&
      std::isfinite(dewarp->scale)) {
    rotation = dewarp->rotation;
    scale = dewarp->scale;
  }

  // Step 3: de-rotate/de-scale the current window (sampled from the panorama, so nothing is
  // lost at its border) when that moves its corners noticeably; else use F_c.
  const runtime::Complex* translation_band_ptr = cur_translation;
  if (std::max(std::abs(rotation), std::abs(std::log(scale))) > minDewarpFor(options.window)) {
    const TaperedWindow tw = loadWarpedWindow(w, panorama, k, rotation, scale);
    w.window_fft.execute();
    cur_translation_noise = w.translation.whiten(w.spectrum.data(), tw.energy, w.derotated.data(),
                                                 options.shift_covariance, noisePower(k));
    removeBlur(k, w.derotated.data());
    translation_band_ptr = w.derotated.data();
  } else if (translation_band_ptr == nullptr) {  // F_c not whitened yet (frame not kept)
    cur_translation_noise = w.translation.whiten(w.spectrum.data(), cur.energy,
                                                 w.scratch_translation.data(),
                                                 options.shift_covariance, noisePower(k));
    removeBlur(k, w.scratch_translation.data());
    translation_band_ptr = w.scratch_translation.data();
  }

  // Step 4: translation, phase correlation of the whitened spectra over the whole surface,
  // or within kExpectedDvReachPx of an expected dv (a peak on that band's border may be
  // cut off: the window is then not used).
  const double everywhere = std::numeric_limits<double>::infinity();
  const runtime::Complex* reference_band = ref.translation.data() + k * translation_band;
  const reg::CorrelationPeak t =
      std::isfinite(expected_dv)
          ? w.translation.correlateNear(reference_band, translation_band_ptr, expected_dv, everywhere)
          : w.translation.correlate(reference_band, translation_band_ptr, everywhere, everywhere);
  if (!std::isfinite(t.shift0) || !std::isfinite(t.shift1) || !std::isfinite(t.confidence)) return;
  out.du = t.shift1;
  out.dv = t.shift0;
  out.confidence = t.confidence;
  if (options.shift_covariance) {
    const reg::PeakCovariance c =
        w.translation.shiftCovariance(ref.translation_noise[static_cast<std::size_t>(k)],
                                      cur_translation_noise, noiseEnergy(k), t);
    out.var_du = c.c11;
    out.var_dv = c.c00;
    out.cov_du_dv = c.c01;
  }
  out.valid = t.confidence > 0.0 && t.confidence >= options.min_confidence && !t.on_border;
}

namespace {
void requireValid(cv::Size panorama, const WindowRegistration::Options& options) {
  detail::throwIfProblems("WindowRegistration", WindowRegistration::validate(panorama, options));
}
}  // namespace

WindowRegistration::WindowRegistration(cv::Size panorama, const Options& options, int threads) {
  std::vector<std::string> problems = validate(panorama, options);
  detail::checkRange(problems, "threads", threads, 0, kMaxThreads, " (0 = all online cores)");
  detail::throwIfProblems("WindowRegistration", problems);
  impl_ = std::make_unique<Impl>(panorama, options, nullptr, threads, runtime::PlanEffort::kMeasure);
}

WindowRegistration::WindowRegistration(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}

WindowRegistration SharedPoolRegistration::make(cv::Size panorama,
                                                const WindowRegistration::Options& options,
                                                runtime::WorkerPool& pool,
                                                runtime::PlanEffort effort) {
  requireValid(panorama, options);
  return WindowRegistration(
      std::make_unique<WindowRegistration::Impl>(panorama, options, &pool, 1, effort));
}

WindowRegistration::~WindowRegistration() = default;

const WindowRegistration::Options& WindowRegistration::options() const { return impl_->options; }

cv::Size WindowRegistration::panoramaSize() const { return {impl_->width, impl_->height}; }

int WindowRegistration::threads() const { return impl_->pool->size(); }

int WindowRegistration::windowCount() const { return impl_->windows; }

double WindowRegistration::minDewarp() const { return minDewarpFor(impl_->options.window); }

double WindowRegistration::windowCenter(int k) const { return impl_->windowCenter(k); }
int WindowRegistration::windowTop() const { return impl_->top; }

void WindowRegistration::Impl::transformInto(const cv::Mat& panorama, WindowSpectra& ref,
                                             bool blurred) {
  transformColumns(panorama);
  auto task = [&](int worker, int k) {
    Worker& w = *workers[worker];
    const auto i = static_cast<std::size_t>(k);
    const TaperedWindow tw =
        transformWindow(w, panorama, k, ref.log_polar.data() + k * log_polar_band);
    ref.textured[k] = tw.textured;
    if (!tw.textured) return;
    runtime::Complex* band = ref.translation.data() + k * translation_band;
    ref.translation_noise[i] = w.translation.whiten(w.spectrum.data(), tw.energy, band,
                                                    options.shift_covariance, noisePower(k));
    if (blurred) removeBlur(k, band);
  };
  pool->run(windows, task);
}

void WindowRegistration::Impl::removeBlur(int k, runtime::Complex* band) const {
  if (!blur_active[static_cast<std::size_t>(k)]) return;
  namespace simd = runtime::simd;
  // blur_kernel holds K / |K|: the band is multiplied by its conjugate.
  const auto* kernel =
      reinterpret_cast<const float*>(blur_kernel.data() + static_cast<std::size_t>(k) * band_cols);
  const std::size_t rows = translation_band / static_cast<std::size_t>(band_cols);
  const int pairs = 2 * (band_cols / 2);
  for (std::size_t r = 0; r < rows; ++r) {
    auto* row = reinterpret_cast<float*>(band + r * band_cols);
    for (int c = 0; c < pairs; c += 2)
      simd::store(row + 2 * c, simd::mulConj(simd::load(row + 2 * c), simd::load(kernel + 2 * c)));
    if (pairs < band_cols) {
      const int c = 2 * pairs;
      const float re = row[c] * kernel[c] + row[c + 1] * kernel[c + 1];
      const float im = row[c + 1] * kernel[c] - row[c] * kernel[c + 1];
      row[c] = re;
      row[c + 1] = im;
    }
  }
}

void WindowRegistration::setMotionBlur(std::span<const float> paths, int samples) {
  Impl& s = *impl_;
  std::fill(s.blur_active.begin(), s.blur_active.end(), 0);
  if (samples < 1 || samples > kMaxBlurSamples ||
      paths.size() < static_cast<std::size_t>(s.windows) * samples)
    return;
  // Window k of a frame blurred along x_j (j < samples: the shifts, in du's sense, of the
  // sharp frames it averages) is the sharp window w(u) averaged as w(u + x_j): its spectrum
  // is the sharp one times K(w) = mean_j exp(i w x_j). With the x_j taken about their mean,
  // conj(K) / |K| takes K's phase out and leaves the window's shift at the mean of the x_j.
  // K at the band's columns w = c * step by the recurrence exp(i c step x) (real arithmetic:
  // std::complex's product checks for NaN and does not vectorise).
  const double step = 2.0 * std::numbers::pi / s.fft_size;  // rad/px between band columns
  std::array<double, kMaxBlurSamples> re{}, im{}, turn_re{}, turn_im{};
  for (int k = 0; k < s.windows; ++k) {
    const float* x = paths.data() + static_cast<std::size_t>(k) * samples;
    double mean = 0.0, lo = x[0], hi = x[0];
    for (int j = 0; j < samples; ++j) {
      mean += x[j];
      lo = std::min<double>(lo, x[j]);
      hi = std::max<double>(hi, x[j]);
    }
    mean /= samples;
    if (!std::isfinite(mean) || !(hi - lo >= kMinBlurExtentPx) || !(hi - lo <= kMaxBlurExtentPx))
      continue;
    for (int j = 0; j < samples; ++j) {
      turn_re[j] = std::cos(step * (x[j] - mean));
      turn_im[j] = std::sin(step * (x[j] - mean));
      re[j] = 1.0;
      im[j] = 0.0;
    }
    runtime::Complex* kernel = s.blur_kernel.data() + static_cast<std::size_t>(k) * s.band_cols;
    for (int c = 0; c < s.band_cols; ++c) {
      double sum_re = 0.0, sum_im = 0.0;
      for (int j = 0; j < samples; ++j) {
        sum_re += re[j];
        sum_im += im[j];
        const double next_re = re[j] * turn_re[j] - im[j] * turn_im[j];
        im[j] = re[j] * turn_im[j] + im[j] * turn_re[j];
        re[j] = next_re;
      }
      const double magnitude = std::hypot(sum_re, sum_im);
      kernel[c] = magnitude > 1e-9 * samples
                      ? runtime::Complex(static_cast<float>(sum_re / magnitude),
                                         static_cast<float>(sum_im / magnitude))
                      : runtime::Complex(1.0f, 0.0f);
    }
    s.blur_active[static_cast<std::size_t>(k)] = 1;
  }
}

void WindowRegistration::setReference(const cv::Mat& panorama) {
  Impl& s = *impl_;
  if (!s.acceptsImage(panorama)) return;
  s.keepPendingKeyframe();
  s.measureNoise(panorama);
  s.transformInto(panorama, *s.reference, true);
  s.has_reference = true;
  s.next_ready = false;
}

bool WindowRegistration::hasReference() const { return impl_->has_reference; }

double WindowRegistration::noiseSigma() const { return impl_->noise_sigma; }

void WindowRegistration::setValidity(const cv::Mat& validity) {
  Impl& s = *impl_;
  if (validity.type() != CV_32FC1 || validity.cols != s.width ||
      validity.rows != s.height)
    throw std::invalid_argument("WindowRegistration::setValidity: expected a CV_32FC1 " +
                                std::to_string(s.width) + "x" +
                                std::to_string(s.height) + " map");
  s.setValidity(validity);
  s.has_reference = false;  // reference spectra were tapered with the old weights
  s.next_ready = false;
  std::fill(s.keyframe_stored.begin(), s.keyframe_stored.end(), 0);
  s.pending_keyframe = -1;
}

int WindowRegistration::maskedWindowCount() const {
  const Impl& s = *impl_;
  return static_cast<int>(std::count(s.mostly_masked.begin(), s.mostly_masked.end(), 1));
}

bool WindowRegistration::measure(const cv::Mat& current, std::span<WindowMotion> out,
                                 bool keep_as_next,
                                 std::span<const WindowMotion> known_rotation_scale,
                                 std::span<const double> expected_dv, int against,
                                 std::span<const WindowMotion> dewarp) {
  Impl& s = *impl_;
  const bool known = !known_rotation_scale.empty();
  const auto windows = static_cast<std::size_t>(s.windows);
  if (against != kPreviousFrame && !hasKeyframe(against)) return false;
  if (!s.has_reference || !s.acceptsImage(current) || out.size() < windows ||
      (known && known_rotation_scale.size() < windows) ||
      (!expected_dv.empty() && expected_dv.size() < windows) ||
      (!dewarp.empty() && dewarp.size() < windows))
    return false;
  WindowSpectra& next = *s.next;
  const WindowSpectra& ref = against == kPreviousFrame ? *s.reference : s.keyframe(against);
  if (keep_as_next) s.measureNoise(current);
  s.transformColumns(current);
  auto task = [&](int worker, int k) {
    Worker& w = *s.workers[worker];
    // Without a search for rotation/scale the current log-polar spectrum is not needed.
    const auto i = static_cast<std::size_t>(k);
    runtime::Complex* cur_log_polar = keep_as_next
                                      ? next.log_polar.data() + k * s.log_polar_band
                                      : (known ? nullptr : w.scratch_log_polar.data());
    const TaperedWindow tw = s.transformWindow(w, current, k, cur_log_polar);
    // The un-rotated F_c is whitened here only when it becomes the next reference;
    // measureWindow() whitens it itself when it needs it.
    runtime::Complex* cur_translation = nullptr;
    reg::PhaseNoise translation_noise{};
    if (keep_as_next) {
      next.textured[k] = tw.textured;
      if (tw.textured) {
        cur_translation = next.translation.data() + k * s.translation_band;
        translation_noise = w.translation.whiten(w.spectrum.data(), tw.energy, cur_translation,
                                                 s.options.shift_covariance, s.noisePower(k));
        s.removeBlur(k, cur_translation);
      }
      next.translation_noise[i] = translation_noise;
    }
    s.measureWindow(w, current, k, tw, cur_translation, translation_noise, cur_log_polar,
                    known ? &known_rotation_scale[k] : nullptr,
                    expected_dv.empty() ? std::numeric_limits<double>::quiet_NaN() : expected_dv[k],
                    dewarp.empty() ? nullptr : &dewarp[k], ref, out[k]);
  };
  s.pool->run(s.windows, task);
  if (keep_as_next) s.next_ready = true;
  return true;
}

void WindowRegistration::advance() {
  Impl& s = *impl_;
  if (!s.next_ready) return;
  s.keepPendingKeyframe();
  std::swap(s.reference, s.next);
  s.next_ready = false;
  s.has_reference = true;
}

void WindowRegistration::reserveKeyframes(int slots) {
  if (slots < 0 || slots > kMaxKeyframeSlots)
    throw std::invalid_argument("WindowRegistration::reserveKeyframes: " + std::to_string(slots) +
                                " slots is outside [0, " + std::to_string(kMaxKeyframeSlots) +
                                "]");
  Impl& s = *impl_;
  s.keyframes.clear();
  for (int i = 0; i < slots; ++i)
    s.keyframes.push_back(
        std::make_unique<WindowSpectra>(s.windows, s.translation_band, s.log_polar_band));
  s.keyframe_stored.assign(static_cast<std::size_t>(slots), 0);
  s.pending_keyframe = -1;
}

int WindowRegistration::keyframeSlots() const {
  return static_cast<int>(impl_->keyframes.size());
}

bool WindowRegistration::storeKeyframe(int slot) {
  Impl& s = *impl_;
  if (!s.has_reference || slot < 0 || slot >= keyframeSlots()) return false;
  if (s.pending_keyframe >= 0 && s.pending_keyframe != slot) {
    // The same reference becomes a second keyframe: the first gets a copy.
    WindowSpectra& to = *s.keyframes[static_cast<std::size_t>(s.pending_keyframe)];
    std::copy_n(s.reference->translation.data(), to.translation.size(), to.translation.data());
    std::copy_n(s.reference->log_polar.data(), to.log_polar.size(), to.log_polar.data());
    to.textured = s.reference->textured;
    to.translation_noise = s.reference->translation_noise;
  }
  // The reference is the keyframe until it is replaced: it moves into the slot then.
  s.pending_keyframe = slot;
  s.keyframe_stored[static_cast<std::size_t>(slot)] = 1;
  return true;
}

bool WindowRegistration::setKeyframe(int slot, const cv::Mat& panorama) {
  Impl& s = *impl_;
  if (slot < 0 || slot >= keyframeSlots() || !s.acceptsImage(panorama)) return false;
  // A slot still shared with the reference (storeKeyframe()) is given up by it: the
  // reference stays the reference, the slot gets spectra of its own.
  if (s.pending_keyframe == slot) s.pending_keyframe = -1;
  s.transformInto(panorama, *s.keyframes[static_cast<std::size_t>(slot)], false);
  s.keyframe_stored[static_cast<std::size_t>(slot)] = 1;
  return true;
}

bool WindowRegistration::hasKeyframe(int slot) const {
  const Impl& s = *impl_;
  return slot >= 0 && slot < keyframeSlots() && s.keyframe_stored[static_cast<std::size_t>(slot)];
}

}  // namespace omnipose
