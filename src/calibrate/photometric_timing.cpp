#include "omnipose/calibrate/photometric_timing.hpp"

#include <Eigen/Cholesky>
#include <Eigen/Eigenvalues>
#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>

#include "common/problem_list.hpp"
#include "omnipose/calibrate/ring_detector.hpp"
#include "omnipose/so3.hpp"

namespace omnipose::calibrate {
namespace {

constexpr int kMinPairs = 10;
/// Fewest pixels a pair must keep inside the ring to count.
constexpr int kMinPixelsPerPair = 200;
/// Spacing of the tabulated orientation, seconds: adjacent entries differ by at most a few
/// tenths of a milliradian, so a normalised linear blend between them is exact enough.
constexpr double kTableStep = 2e-4;
/// How far the table reaches beyond the frames' times, seconds: the offset may move that far.
constexpr double kTableMargin = 0.02;
/// Finite-difference steps of the geometry, seconds.
constexpr double kReadoutDelta = 1e-4;
constexpr double kOffsetDelta = 1e-4;
constexpr double kMountingDelta = 1e-4;  ///< radians
/// Fixed-point steps for the row time of the pixel a bearing lands on.
constexpr int kRowTimeSteps = 3;
/// Pixels kept clear of the ring's edges: the warped pixel and its neighbours stay inside.
constexpr double kEdgePx = 3.0;

/// The camera's orientation R_{c(t_begin)}^T R_{c(t)} at IMU-clock times t (offset 0), from
/// the gyro, tabulated every kTableStep seconds.
class OrientationTable {
 public:
  OrientationTable(std::span<const GyroSample> samples, const ImuCalibration& imu,
                   const Eigen::Vector3d& bias, double t_begin, double t_end, double max_gap_s)
      : begin_(t_begin) {
    const int n = std::max(1, static_cast<int>(std::ceil((t_end - t_begin) / kTableStep)));
    q_.reserve(n + 1);
    q_.push_back(Eigen::Quaterniond::Identity());
    invalid_before_.assign(n + 1, 0);
    for (int i = 0; i < n; ++i) {
      const double a = begin_ + i * kTableStep;
      const auto R = integrateGyro(samples, imu, bias, a, a + kTableStep, max_gap_s);
      q_.push_back(R ? (q_.back() * Eigen::Quaterniond(*R)).normalized() : q_.back());
      invalid_before_[i + 1] = invalid_before_[i] + (R ? 0 : 1);
    }
  }

  /// Whether the gyro covers [a, b] without a gap.
  bool covers(double a, double b) const {
    const int i = segment(a), j = segment(b);
    return i >= 0 && j >= 0 && invalid_before_[j + 1] == invalid_before_[i];
  }

  /// The orientation at t; nullopt outside the table or in a gap.
  std::optional<Eigen::Quaterniond> at(double t) const {
    const int i = segment(t);
    if (i < 0 || invalid_before_[i + 1] != invalid_before_[i]) return std::nullopt;
    const double f = (t - begin_) / kTableStep - i;
    return Eigen::Quaterniond(q_[i].coeffs() * (1.0 - f) + q_[i + 1].coeffs() * f).normalized();
  }

 private:
  /// The table segment holding t, -1 outside.
  int segment(double t) const {
    const double x = (t - begin_) / kTableStep;
    if (!(x >= 0.0) || x >= static_cast<double>(q_.size() - 1)) return -1;
    return static_cast<int>(x);
  }

  double begin_;
  std::vector<Eigen::Quaterniond> q_;
  std::vector<int> invalid_before_;  ///< invalid segments before entry i
};


/// The frame pixels a frame pair may use: inside the ring and the calibration's mask.
struct RingMasks {
  cv::Mat ring;   ///< where a warped pixel may land
  cv::Mat inner;  ///< the same kEdgePx inside the ring's edges: where the pixels are chosen
};

RingMasks ringMasks(const Calibration& calibration) {
  const int rows = calibration.omni.image_height, cols = calibration.omni.image_width;
  RingMasks m{cv::Mat(rows, cols, CV_8U, cv::Scalar(0)), cv::Mat(rows, cols, CV_8U, cv::Scalar(0))};
  const double r_in = calibration.omni.radius_inner, r_out = calibration.omni.radius_outer;
  for (int y = 0; y < rows; ++y)
    for (int x = 0; x < cols; ++x) {
      if (!calibration.omni.mask.empty() && calibration.omni.mask.at<uchar>(y, x) == 0) continue;
      const double r = calibration.ringRadius(x, y);
      if (r >= r_in && r <= r_out) m.ring.at<uchar>(y, x) = 255;
      if (r >= r_in + kEdgePx && r <= r_out - kEdgePx) m.inner.at<uchar>(y, x) = 255;
    }
  return m;
}

/// `frame` (any depth; gray, BGR or BGRA) smoothed and normalised to zero mean and unit
/// variance over the ring, CV_32F.
cv::Mat prepare(const cv::Mat& frame, const cv::Mat& ring, double sigma) {
  cv::Mat image = toGreyFloat(frame);
  if (sigma > 0.0) cv::GaussianBlur(image, image, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
  cv::Scalar mean, stddev;
  cv::meanStdDev(image, mean, stddev, ring);
  return (image - mean[0]) / std::max(stddev[0], 1e-6);
}

/// Bilinear sample of a CV_32F image at (x, y), inside [0, cols - 1) x [0, rows - 1).
float sample(const cv::Mat& m, double x, double y) {
  const int x0 = static_cast<int>(x), y0 = static_cast<int>(y);
  const float fx = static_cast<float>(x - x0), fy = static_cast<float>(y - y0);
  const float* a = m.ptr<float>(y0) + x0;
  const float* b = m.ptr<float>(y0 + 1) + x0;
  return (1.0f - fy) * ((1.0f - fx) * a[0] + fx * a[1]) + fy * ((1.0f - fx) * b[0] + fx * b[1]);
}

/// The central-difference gradient of `m` bilinearly interpolated at (x, y), inside
/// [1, cols - 2) x [1, rows - 2) (per pixel; not stored: a frame's gradient images would triple
/// the memory of a long recording).
Eigen::Vector2d gradient(const cv::Mat& m, double x, double y) {
  return {0.5 * (sample(m, x + 1.0, y) - sample(m, x - 1.0, y)),
          0.5 * (sample(m, x, y + 1.0) - sample(m, x, y - 1.0))};
}

/// A pixel of the later frame of a pair.
struct Pixel {
  float x = 0.0f, y = 0.0f, value = 0.0f;
  Eigen::Vector3d bearing;
};

/// The `count` strongest-gradient pixels of `frame` inside `inner` (ring inset).
std::vector<Pixel> strongestPixels(const Calibration& calibration, const cv::Mat& frame,
                                   const cv::Mat& inner, int count) {
  cv::Mat gx, gy;
  cv::Sobel(frame, gx, CV_32F, 1, 0, 1, 0.5, 0.0, cv::BORDER_REPLICATE);
  cv::Sobel(frame, gy, CV_32F, 0, 1, 1, 0.5, 0.0, cv::BORDER_REPLICATE);
  std::vector<std::pair<float, cv::Point>> candidates;
  for (int y = 0; y < inner.rows; ++y)
    for (int x = 0; x < inner.cols; ++x) {
      if (!inner.at<uchar>(y, x)) continue;
      const float dx = gx.at<float>(y, x), dy = gy.at<float>(y, x);
      candidates.emplace_back(dx * dx + dy * dy, cv::Point(x, y));
    }
  const auto keep = std::min<std::size_t>(candidates.size(), static_cast<std::size_t>(count));
  std::nth_element(candidates.begin(), candidates.begin() + keep, candidates.end(),
                   [](const auto& a, const auto& b) { return a.first > b.first; });
  std::vector<Pixel> pixels;
  pixels.reserve(keep);
  for (std::size_t i = 0; i < keep; ++i) {
    const cv::Point p = candidates[i].second;
    const auto b = calibration.bearingOfPixel(p.x, p.y);
    if (!b) continue;
    pixels.push_back({static_cast<float>(p.x), static_cast<float>(p.y), frame.at<float>(p), *b});
  }
  return pixels;
}

/// What is estimated: the readout, the clock offset and a small rotation (rotation vector,
/// camera axes, radians) correcting the mounting: the camera turns at exp([mounting]x) X w.
struct Params {
  double readout = 0.0, offset = 0.0;
  Eigen::Vector3d mounting = Eigen::Vector3d::Zero();
};
constexpr int kParams = 5;
using Vector5d = Eigen::Matrix<double, kParams, 1>;
using Matrix5d = Eigen::Matrix<double, kParams, kParams>;

/// The geometry of one evaluation.
struct Geometry {
  double readout = 0.0, offset = 0.0;
  Eigen::Quaterniond mounting = Eigen::Quaterniond::Identity();  ///< exp([mounting]x)
};

Geometry geometryOf(const Params& p) {
  return {p.readout, p.offset, Eigen::Quaterniond(rotationFromVector(p.mounting))};
}

/// Where pixel `p` of the frame at t1 lands in the frame at t0 with `at`; nullopt where the
/// gyro or the lens cannot tell. A mounting corrected by Q turns every rate by Q, so the
/// rotation between two instants becomes Q R Q^T.
std::optional<Eigen::Vector2d> warp(const Calibration& calibration, const OrientationTable& table,
                                    const Pixel& p, double t0, double t1, const Geometry& at) {
  const int rows = calibration.omni.image_height;
  const auto w1 = table.at(t1 + rowTime(p.y, rows, at.readout) - at.offset);
  if (!w1) return std::nullopt;
  const Eigen::Vector3d b1 = at.mounting.conjugate() * p.bearing;
  Eigen::Vector2d q(p.x, p.y);
  for (int step = 0; step < kRowTimeSteps; ++step) {
    const auto w0 = table.at(t0 + rowTime(q.y(), rows, at.readout) - at.offset);
    if (!w0) return std::nullopt;
    const auto landed = calibration.pixelOfBearing(at.mounting * ((w0->conjugate() * *w1) * b1));
    if (!landed || !std::isfinite(landed->x()) || !std::isfinite(landed->y())) return std::nullopt;
    q = *landed;
  }
  return q;
}

/// One pixel's residual and its derivatives by the parameters (Params' order).
struct Residual {
  float r = 0.0f;
  float J[kParams] = {};
};

/// The residuals of pair (k, k+1) at `params` (only the pixels that stay inside the ring).
void pairResiduals(const Calibration& calibration, const OrientationTable& table,
                   const cv::Mat& earlier, const cv::Mat& ring, const std::vector<Pixel>& pixels,
                   double t0, double t1, const Params& params, std::vector<Residual>& out) {
  out.clear();
  const Geometry at = geometryOf(params);
  // The geometry with each parameter moved by its finite-difference step.
  std::array<Geometry, kParams> moved;
  std::array<double, kParams> delta{};
  const bool rolling = params.readout != 0.0;
  for (int j = 0; j < kParams; ++j) {
    Params p = params;
    delta[j] = j == 0 ? std::copysign(kReadoutDelta, params.readout) : j == 1 ? kOffsetDelta : kMountingDelta;
    if (j == 0) p.readout += delta[j];
    else if (j == 1) p.offset += delta[j];
    else p.mounting(j - 2) += delta[j];
    moved[j] = geometryOf(p);
  }
  const double x_max = ring.cols - 3.0, y_max = ring.rows - 3.0;
  for (const Pixel& p : pixels) {
    const auto q = warp(calibration, table, p, t0, t1, at);
    if (!q || !(q->x() >= 1.0 && q->x() < x_max && q->y() >= 1.0 && q->y() < y_max)) continue;
    if (!ring.at<uchar>(static_cast<int>(std::lround(q->y())), static_cast<int>(std::lround(q->x()))))
      continue;
    const Eigen::Vector2d g = gradient(earlier, q->x(), q->y());
    Residual r;
    r.r = p.value - sample(earlier, q->x(), q->y());
    bool ok = true;
    for (int j = rolling ? 0 : 1; j < kParams && ok; ++j) {
      const auto qj = warp(calibration, table, p, t0, t1, moved[j]);
      ok = qj.has_value();
      if (ok) r.J[j] = static_cast<float>(-g.dot(*qj - *q) / delta[j]);
    }
    if (ok) out.push_back(r);
  }
}

/// Robust sigma (1.4826 MAD) of every residual.
double robustSigma(const std::vector<std::vector<Residual>>& residuals) {
  std::vector<float> magnitudes;
  for (const auto& pair : residuals)
    for (const Residual& r : pair) magnitudes.push_back(std::abs(r.r));
  if (magnitudes.empty()) return 0.0;
  const auto middle = magnitudes.begin() + static_cast<std::ptrdiff_t>(magnitudes.size() / 2);
  std::nth_element(magnitudes.begin(), middle, magnitudes.end());
  return 1.4826 * *middle;
}

/// One refinement's data: the gyro's orientation, the ring, the pairs the gyro covers, the
/// frames prepared and each pair's pixels.
struct Problem {
  Problem(const Calibration& calibration, std::span<const cv::Mat> frames,
          std::span<const double> times, std::span<const GyroSample> samples,
          const Eigen::Vector3d& bias, const PhotometricTimingOptions& options)
      : reach(1.5 * std::abs(calibration.sensor.readout_s) + kTableMargin),
        table(samples, atZeroOffset(*calibration.imu), bias,
              times.front() - calibration.imu->time_offset_s - kTableMargin,
              times.back() - calibration.imu->time_offset_s + reach, options.max_gap_s),
        masks(ringMasks(calibration)) {
    const double offset = calibration.imu->time_offset_s;
    for (std::size_t k = 0; k + 1 < frames.size(); ++k)
      if (times[k + 1] > times[k] && table.covers(times[k] - offset - 0.5 * kTableMargin,
                                                  times[k + 1] - offset + reach - 0.5 * kTableMargin))
        pairs.push_back(k);
    if (static_cast<int>(pairs.size()) < kMinPairs) return;
    prepared.resize(frames.size());
    cv::parallel_for_(cv::Range(0, static_cast<int>(frames.size())), [&](const cv::Range& range) {
      for (int k = range.start; k < range.end; ++k) prepared[k] = prepare(frames[k], masks.ring, options.blur_sigma_px);
    });
    pixels.resize(pairs.size());
    cv::parallel_for_(cv::Range(0, static_cast<int>(pairs.size())), [&](const cv::Range& range) {
      for (int i = range.start; i < range.end; ++i)
        pixels[i] = strongestPixels(calibration, prepared[pairs[i] + 1], masks.inner, options.pixels_per_frame);
    });
  }

  static ImuCalibration atZeroOffset(ImuCalibration imu) {
    imu.time_offset_s = 0.0;
    return imu;
  }

  double reach;                 ///< how far past a frame's stamp its rows may be read, seconds
  OrientationTable table;       ///< on the IMU's clock (offset 0)
  RingMasks masks;
  std::vector<std::size_t> pairs;  ///< k of each pair (k, k+1) the gyro covers
  std::vector<cv::Mat> prepared;   ///< every frame, prepare()d
  std::vector<std::vector<Pixel>> pixels;  ///< per pair, of its later frame
};

/// The normal equations of the pixels with Huber weights, each pair's gradient (for the
/// sandwich) and the residuals' robust variance.
struct Normal {
  Matrix5d H = Matrix5d::Zero();
  std::vector<Vector5d> gradients;
  double variance = 1.0;
  int used = 0;               ///< pairs with kMinPixelsPerPair residuals
  double residual_rms = 0.0;  ///< unweighted, every residual
};

Normal normalEquations(const std::vector<std::vector<Residual>>& residuals, double huber_sigmas) {
  Normal n;
  const double sigma = std::max(robustSigma(residuals), 1e-9);
  n.variance = sigma * sigma;
  const double k = huber_sigmas * sigma;
  n.gradients.assign(residuals.size(), Vector5d::Zero());
  double sum_squares = 0.0;
  long count = 0;
  for (std::size_t i = 0; i < residuals.size(); ++i) {
    if (static_cast<int>(residuals[i].size()) < kMinPixelsPerPair) continue;
    ++n.used;
    for (const Residual& r : residuals[i]) {
      const double w = std::abs(r.r) <= k ? 1.0 : k / std::abs(r.r);
      const Vector5d J = Eigen::Map<const Eigen::Matrix<float, kParams, 1>>(r.J).cast<double>();
      n.H.selfadjointView<Eigen::Lower>().rankUpdate(J, w);
      n.gradients[i] += w * r.r * J;
      sum_squares += static_cast<double>(r.r) * r.r;
      ++count;
    }
  }
  n.H = n.H.selfadjointView<Eigen::Lower>();
  n.residual_rms = count > 0 ? std::sqrt(sum_squares / count) : 0.0;
  return n;
}

/// Gauss-Newton from `params` (updated) on the objective sum w r^2 / variance +
/// |mounting|^2 * prior; `covariance` the sandwich at the last step. False (out.summary says
/// why) when too few pairs keep their pixels or the system is singular.
bool gaussNewton(const Problem& problem, const Calibration& calibration, std::span<const double> times,
                 double prior, const PhotometricTimingOptions& options, Params& params,
                 Matrix5d& covariance, PhotometricTiming& out) {
  const bool rolling = params.readout != 0.0;
  std::vector<std::vector<Residual>> residuals(problem.pairs.size());
  for (out.iterations = 1; out.iterations <= options.max_iterations; ++out.iterations) {
    cv::parallel_for_(cv::Range(0, static_cast<int>(problem.pairs.size())), [&](const cv::Range& range) {
      for (int i = range.start; i < range.end; ++i) {
        const std::size_t k = problem.pairs[i];
        pairResiduals(calibration, problem.table, problem.prepared[k], problem.masks.ring, problem.pixels[i],
                      times[k], times[k + 1], params, residuals[i]);
      }
    });
    const Normal n = normalEquations(residuals, options.huber_sigmas);
    out.residual_rms = n.residual_rms;
    if (n.used < kMinPairs) {
      out.summary = "cannot: " + std::to_string(n.used) + " frame pairs keep " +
                    std::to_string(kMinPixelsPerPair) + " pixels inside the ring, at least " +
                    std::to_string(kMinPairs) + " needed";
      return false;
    }
    Vector5d g = Vector5d::Zero();
    Matrix5d B = Matrix5d::Zero();
    for (const Vector5d& gi : n.gradients) {
      g += gi / n.variance;
      B += gi * gi.transpose() / (n.variance * n.variance);
    }
    Matrix5d A = n.H / n.variance;
    A.bottomRightCorner<3, 3>().diagonal().array() += prior;
    g.tail<3>() += prior * params.mounting;
    // Solved scaled to a unit diagonal (seconds and radians weigh alike); a global shutter's
    // readout is not estimated: its column is zero, its step zero.
    if (!rolling) A(0, 0) = 1.0;
    const Vector5d scale = A.diagonal().cwiseMax(std::numeric_limits<double>::min()).cwiseSqrt().cwiseInverse();
    const Eigen::LDLT<Matrix5d> solver(scale.asDiagonal() * A * scale.asDiagonal());
    if (solver.info() != Eigen::Success || !(solver.rcond() > 1e-12)) {
      out.summary = "cannot: the pixels cannot tell the clock, the mounting and the readout apart "
                    "(the rate of turn hardly changes)";
      return false;
    }
    const Matrix5d Ainv = scale.asDiagonal() * solver.solve(Matrix5d::Identity()) * scale.asDiagonal();
    Matrix5d information = B * (static_cast<double>(n.used) / std::max(1, n.used - kParams));
    information.bottomRightCorner<3, 3>().diagonal().array() += prior;
    covariance = Ainv * information * Ainv;
    const Vector5d step = -Ainv * g;
    params.readout += step(0);
    params.offset += step(1);
    params.mounting += step.tail<3>();
    if ((step.array().abs() <= 0.01 * covariance.diagonal().array().sqrt()).all()) break;
  }
  out.iterations = std::min(out.iterations, options.max_iterations);
  return true;
}

/// `out` filled from the estimate and judged: found, or refused with the reason when the
/// readout ran away or an uncertainty exceeds what `options` allow.
void judge(const Params& params, const Matrix5d& covariance, const Calibration& calibration,
           const PhotometricTimingOptions& options, PhotometricTiming& out) {
  const bool rolling = calibration.sensor.readout_s != 0.0;
  out.readout_s = params.readout;
  out.time_offset_s = params.offset;
  out.rotation = (Eigen::Quaterniond(rotationFromVector(params.mounting)) * calibration.imu->rotation).normalized();
  out.readout_sigma_s = std::sqrt(covariance(0, 0));
  out.time_offset_sigma_s = std::sqrt(covariance(1, 1));
  out.correlation = covariance(0, 1) / std::max(out.readout_sigma_s * out.time_offset_sigma_s,
                                                std::numeric_limits<double>::min());
  const Eigen::Matrix3d mounting = covariance.bottomRightCorner<3, 3>();
  out.rotation_sigma_deg =
      std::sqrt(Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(mounting).eigenvalues().maxCoeff()) * 180.0 /
      std::numbers::pi;
  out.rotation_change_deg = params.mounting.norm() * 180.0 / std::numbers::pi;
  char text[320];
  std::snprintf(text, sizeof(text),
                "time offset %+.6f s +-%.6f, mounting moved %.3f deg +-%.3f, from the pixels of %d "
                "pairs, %d Gauss-Newton steps, residual %.3f",
                out.time_offset_s, out.time_offset_sigma_s, out.rotation_change_deg,
                out.rotation_sigma_deg, out.pairs, out.iterations, out.residual_rms);
  std::string measured = text;
  if (rolling) {
    std::snprintf(text, sizeof(text), "readout %.6f s +-%.6f (%.2f %%, correlation with the offset %+.2f), ",
                  out.readout_s, out.readout_sigma_s,
                  100.0 * out.readout_sigma_s / std::abs(out.readout_s), out.correlation);
    measured = text + measured;
    if (!(std::abs(out.readout_s) <= SensorTiming::kMaxReadoutS) ||
        std::signbit(out.readout_s) != std::signbit(calibration.sensor.readout_s)) {
      out.summary = "cannot: the readout ran away (" + measured + ")";
      return;
    }
    if (!(out.readout_sigma_s <= options.max_readout_sigma * std::abs(out.readout_s))) {
      out.summary = "cannot: the readout is not determined (" + measured +
                    "): record the robot turning in place (the pixels are compared as if the "
                    "camera only turned), speeding up, slowing down and shaking";
      return;
    }
  }
  if (!(out.time_offset_sigma_s <= options.max_offset_sigma_s)) {
    out.summary = "cannot: the clock offset is not determined (" + measured + ")";
    return;
  }
  out.found = true;
  out.summary = measured;
}

/// Why `frames` cannot be used (empty: they can): fewer than two, or one not of the
/// calibration's omni size.
std::string framesProblem(const Calibration& calibration, std::span<const cv::Mat> frames) {
  if (frames.size() < 2) return "fewer than two frames";
  const cv::Size omni(calibration.omni.image_width, calibration.omni.image_height);
  for (std::size_t k = 0; k < frames.size(); ++k)
    if (frames[k].size() != omni || frames[k].empty())
      return "frame " + std::to_string(k) + " is " + std::to_string(frames[k].cols) + "x" +
             std::to_string(frames[k].rows) + ", not the calibration's omni image (" +
             std::to_string(omni.width) + "x" + std::to_string(omni.height) + ")";
  return {};
}

}  // namespace

std::vector<std::string> PhotometricTimingOptions::validate() const {
  std::vector<std::string> p;
  if (pixels_per_frame <= 0) p.push_back("pixels_per_frame: must be > 0");
  if (!(blur_sigma_px >= 0.0 && std::isfinite(blur_sigma_px)))
    p.push_back("blur_sigma_px: must be a finite number >= 0");
  if (max_iterations <= 0) p.push_back("max_iterations: must be > 0");
  if (!(huber_sigmas > 0.0 && std::isfinite(huber_sigmas)))
    p.push_back("huber_sigmas: must be a finite number > 0");
  if (!(max_gap_s > 0.0 && std::isfinite(max_gap_s))) p.push_back("max_gap_s: must be a finite number > 0");
  if (!(max_readout_sigma > 0.0 && std::isfinite(max_readout_sigma)))
    p.push_back("max_readout_sigma: must be a finite number > 0");
  if (!(max_offset_sigma_s > 0.0 && std::isfinite(max_offset_sigma_s)))
    p.push_back("max_offset_sigma_s: must be a finite number > 0");
  return p;
}

PhotometricTiming refineTimingFromPixels(const Calibration& calibration,
                                         std::span<const cv::Mat> frames,
                                         std::span<const double> times_s,
                                         std::span<const GyroSample> samples,
                                         const Eigen::Vector3d& bias, double mounting_sigma_rad,
                                         const PhotometricTimingOptions& options) {
  detail::throwIfProblems("refineTimingFromPixels: invalid options", options.validate());
  if (frames.size() != times_s.size())
    throw std::invalid_argument("refineTimingFromPixels: " + std::to_string(frames.size()) +
                                " frames but " + std::to_string(times_s.size()) + " times");
  if (!calibration.imu)
    throw std::invalid_argument("refineTimingFromPixels: the calibration needs an imu section");
  if (!(mounting_sigma_rad > 0.0 && std::isfinite(mounting_sigma_rad)))
    throw std::invalid_argument("refineTimingFromPixels: mounting_sigma_rad must be a finite number > 0");
  PhotometricTiming out;
  if (const std::string why = framesProblem(calibration, frames); !why.empty()) {
    out.summary = "cannot: " + why;
    return out;
  }
  const Problem problem(calibration, frames, times_s, samples, bias, options);
  out.pairs = static_cast<int>(problem.pairs.size());
  if (out.pairs < kMinPairs) {
    out.summary = "cannot: " + std::to_string(out.pairs) +
                  " consecutive frame pairs inside the gyro's recording without a gap, at least " +
                  std::to_string(kMinPairs) + " needed";
    return out;
  }
  // The mounting's correction is held to how well the pairs' rotations knew it (a prior of
  // mounting_sigma_rad per axis): a recording that turns about one axis only leaves it there.
  const double prior = 1.0 / (mounting_sigma_rad * mounting_sigma_rad);
  Params params{calibration.sensor.readout_s, calibration.imu->time_offset_s, Eigen::Vector3d::Zero()};
  Matrix5d covariance = Matrix5d::Zero();
  if (!gaussNewton(problem, calibration, times_s, prior, options, params, covariance, out)) return out;
  judge(params, covariance, calibration, options, out);
  return out;
}

}  // namespace omnipose::calibrate
