#include "omnipose/calibrate/imu_estimation.hpp"

#include <Eigen/Eigenvalues>
#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>

#include "common/format.hpp"
#include "common/problem_list.hpp"
#include "omnipose/so3.hpp"

namespace omnipose::calibrate {
namespace {

constexpr int kMinPairs = 10;
/// Alternations of mounting and bias per offset.
constexpr int kAlternations = 4;

/// `v` with `digits` decimals.
std::string fixed(double v, int digits = 4) { return detail::fixed(v, digits); }

/// A consecutive pair's rotation as the images measured it.
struct ImagePair {
  double t0 = 0.0, t1 = 0.0;                       ///< the frames' timestamps, seconds
  Eigen::Vector3d a = Eigen::Vector3d::Zero();     ///< rotation vector, camera axes
};

/// Every consecutive tracked pair of `frames`; with `gyro` (and calibration.imu) registered
/// with each row's rotation within its frame from the gyro, frame k exposed for exposures[k]
/// (empty: the calibration's exposure). The windows' yaw is read at the model's capture times
/// (PipelineOptions::yaw_capture_time off): measured against the gyro at the clock offset
/// being searched, the pairs' yaw would follow that offset's error. Nor is the pairs' rotation
/// combined with the gyro's (PipelineOptions::gyro_fusion off): it would carry the mounting
/// and clock being measured into the measurement.
std::vector<ImagePair> imagePairs(const Calibration& calibration, std::span<const cv::Mat> frames,
                                  std::span<const double> times, OdometryOptions options,
                                  std::span<const GyroSample> gyro = {},
                                  std::span<const double> exposures = {}) {
  options.pipeline.yaw_capture_time = false;
  options.pipeline.gyro_fusion = false;
  Odometry odometry(calibration, options);
  std::vector<ImagePair> pairs;
  std::size_t next = 0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    FrameStamp stamp{.time_s = times[k]};
    if (!exposures.empty()) stamp.exposure_s = exposures[k];
    if (!gyro.empty()) {
      const std::span<const GyroSample> rest = gyro.subspan(next);
      const SensorTiming& sensor = calibration.sensor;
      const std::size_t n = gyroSamplesArrivedBy(
          rest, *calibration.imu, sensor.exposureEndAfterStamp(sensor.exposureOf(stamp.exposure_s)),
          times[k]);
      odometry.addGyro(rest.first(n));
      next += n;
    }
    const auto r = odometry.process(frames[k], stamp);
    if (!r || r->state != TrackState::kTracked || r->reference_sequence != r->sequence - 1 ||
        k == 0)
      continue;
    pairs.push_back({times[k - 1], times[k], r->relative.estimate.omega});
  }
  return pairs;
}

/// The mounting, bias and score at one clock offset.
struct Fit {
  Eigen::Matrix3d X = Eigen::Matrix3d::Identity();  ///< camera from IMU
  Eigen::Vector3d bias = Eigen::Vector3d::Zero();
  double score = 0.0;                               ///< mean squared residual, rad^2
  std::vector<Eigen::Vector3d> g;                   ///< the pairs' gyro rotations (IMU axes)
};

/// The rotation X minimising sum |a_k - X g_k|^2 (Kabsch).
Eigen::Matrix3d align(const std::vector<ImagePair>& pairs, const std::vector<Eigen::Vector3d>& g) {
  Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
  for (std::size_t k = 0; k < pairs.size(); ++k) H += g[k] * pairs[k].a.transpose();
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(H, Eigen::ComputeFullU | Eigen::ComputeFullV);
  Eigen::Matrix3d D = Eigen::Matrix3d::Identity();
  D(2, 2) = (svd.matrixV() * svd.matrixU().transpose()).determinant() < 0.0 ? -1.0 : 1.0;
  return svd.matrixV() * D * svd.matrixU().transpose();
}

/// The fit at clock offset `offset`; nullopt when the samples do not cover every pair.
std::optional<Fit> fitAt(const std::vector<ImagePair>& pairs, std::span<const GyroSample> samples,
                         double offset, double max_gap_s) {
  Fit fit;
  ImuCalibration clock;
  clock.time_offset_s = offset;
  fit.g.resize(pairs.size());
  // The pairs' gyro rotations with the current bias; false when a pair is not covered.
  const auto integrate = [&] {
    for (std::size_t k = 0; k < pairs.size(); ++k) {
      const auto R = integrateGyro(samples, clock, fit.bias, pairs[k].t0, pairs[k].t1, max_gap_s);
      if (!R) return false;
      fit.g[k] = rotationVector(*R);
    }
    return true;
  };
  for (int iteration = 0; iteration < kAlternations; ++iteration) {
    if (!integrate()) return std::nullopt;
    fit.X = align(pairs, fit.g);
    // With the bias off by db, g_k is off by -db dt_k: the least-squares correction.
    Eigen::Vector3d numerator = Eigen::Vector3d::Zero();
    double denominator = 0.0;
    for (std::size_t k = 0; k < pairs.size(); ++k) {
      const double dt = pairs[k].t1 - pairs[k].t0;
      numerator += dt * (fit.X.transpose() * pairs[k].a - fit.g[k]);
      denominator += dt * dt;
    }
    fit.bias -= numerator / denominator;
  }
  if (!integrate()) return std::nullopt;
  fit.score = 0.0;
  for (std::size_t k = 0; k < pairs.size(); ++k)
    fit.score += (pairs[k].a - fit.X * fit.g[k]).squaredNorm();
  fit.score /= static_cast<double>(pairs.size());
  return fit;
}

/// The pairs the samples cover without a gap at every offset of the search (with a margin of
/// 10 ms): a gap in the recording leaves out the pairs near it, not the whole search.
std::vector<ImagePair> coveredPairs(const std::vector<ImagePair>& pairs,
                                    std::span<const GyroSample> samples, double max_offset,
                                    double max_gap_s) {
  std::vector<ImagePair> covered;
  const double margin = max_offset + 0.01;
  for (const ImagePair& p : pairs)
    if (integrateGyro(samples, ImuCalibration{}, Eigen::Vector3d::Zero(), p.t0 - margin, p.t1 + margin,
                      max_gap_s))
      covered.push_back(p);
  return covered;
}

/// The uncertainties of `fit`, with the score's curvature at its offset (per offset^2, of the
/// mean) from the fine grid. Returns how much the recording turns about its weakest axis
/// against its strongest (root of the ratio of the extreme eigenvalues of the information).
double measureUncertainty(const std::vector<ImagePair>& pairs, const Fit& fit, double curvature,
                          ImuEstimate& out) {
  const double n = static_cast<double>(pairs.size());
  const double sum = fit.score * n;
  const double sigma2 = sum / std::max(1.0, 3.0 * n - 7.0);
  Eigen::Matrix3d information = Eigen::Matrix3d::Zero();
  double dt2 = 0.0;
  for (std::size_t k = 0; k < pairs.size(); ++k) {
    const Eigen::Matrix3d G = skew(fit.g[k]);
    information += G.transpose() * G;
    dt2 += std::pow(pairs[k].t1 - pairs[k].t0, 2);
  }
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(information);
  const double weakest = std::max(eigen.eigenvalues()(0), 1e-300);
  out.rotation_sigma_deg = std::sqrt(sigma2 / weakest) * 180.0 / std::numbers::pi;
  out.bias_sigma = Eigen::Vector3d::Constant(std::sqrt(sigma2 / dt2));
  // sum(d) ~ sum_min + (n curvature / 2) (d - d_min)^2: var(d) = 2 sigma2 / (n curvature).
  out.time_offset_sigma_s = curvature > 0.0 ? std::sqrt(2.0 * sigma2 / (n * curvature))
                                            : std::numeric_limits<double>::infinity();
  out.residual_rms_rad = std::sqrt(fit.score);
  return std::sqrt(weakest / std::max(eigen.eigenvalues()(2), 1e-300));
}

/// The lowest point of a score on a grid, refined.
struct Minimum {
  double at = 0.0;         ///< where
  double lowest = 0.0;     ///< the lowest grid point
  double curvature = 0.0;  ///< the score's second derivative there (0: not known)
};

/// The lowest of `points` (position, score; in order, spaced by h) moved to the vertex of the
/// parabola through it and its neighbours when it has both and the parabola opens upwards.
Minimum vertex(const std::vector<std::pair<double, double>>& points, double h) {
  const auto lowest = std::min_element(points.begin(), points.end(),
                                       [](const auto& a, const auto& b) { return a.second < b.second; });
  Minimum m{lowest->first, lowest->first, 0.0};
  if (lowest == points.begin() || lowest + 1 == points.end()) return m;
  const double s0 = (lowest - 1)->second, s1 = lowest->second, s2 = (lowest + 1)->second;
  m.curvature = (s0 - 2.0 * s1 + s2) / (h * h);
  if (m.curvature > 0.0) m.at += 0.5 * h * (s0 - s2) / (s0 - 2.0 * s1 + s2);
  return m;
}

/// The clock offset of the best fit on a grid of `step` within +-`half_width` of `center`,
/// refined (vertex()); every offset tried goes to `curve`. Nullopt when the samples cover the
/// pairs at none of them.
std::optional<Minimum> searchOffset(const std::vector<ImagePair>& pairs,
                                    std::span<const GyroSample> samples, double center,
                                    double half_width, double step, double max_gap_s,
                                    std::vector<std::pair<double, double>>& curve) {
  const int steps = static_cast<int>(std::round(half_width / step));
  std::vector<std::pair<double, double>> grid;
  for (int i = -steps; i <= steps; ++i) {
    const double d = center + i * step;
    if (const auto fit = fitAt(pairs, samples, d, max_gap_s)) grid.emplace_back(d, fit->score);
  }
  curve.insert(curve.end(), grid.begin(), grid.end());
  if (grid.empty()) return std::nullopt;
  return vertex(grid, step);
}

/// A refusal: out.summary says why; false.
bool cannot(ImuEstimate& out, const std::string& what) {
  out.summary = "cannot: " + what;
  return false;
}

/// A clock's estimate: its offset and the fit there.
struct Clock {
  Minimum offset;
  Fit fit;
};

/// The imu section of `clock`'s estimate: its mounting and offset.
ImuCalibration imuOf(const Clock& clock) {
  ImuCalibration imu;
  imu.rotation = Eigen::Quaterniond(clock.fit.X).normalized();
  imu.time_offset_s = clock.offset.at;
  return imu;
}

/// The clock offset, mounting and bias from `pairs`: the offset on the coarse grid over
/// +-max_offset_s, on the fine grid around the best, the fit at the vertex. Nullopt (with
/// out.summary) when the best offset is at the end of the range or the samples do not cover
/// the pairs; every offset tried goes to out.curve.
std::optional<Clock> searchClock(const std::vector<ImagePair>& pairs, std::span<const GyroSample> samples,
                                 const ImuSearchOptions& options, ImuEstimate& out) {
  const auto coarse = searchOffset(pairs, samples, 0.0, options.max_offset_s, options.coarse_step_s,
                                   options.max_gap_s, out.curve);
  if (!coarse) {
    cannot(out, "the gyro's recording does not cover the frame pairs at any clock offset tried");
    return std::nullopt;
  }
  const int half = static_cast<int>(std::floor(options.max_offset_s / options.coarse_step_s + 1e-9));
  if (std::abs(coarse->lowest) >= half * options.coarse_step_s - 1e-9) {
    cannot(out, "the best clock offset is at the end of the range tried (" + fixed(coarse->lowest) +
                    " s of +-" + fixed(options.max_offset_s) + " s)");
    return std::nullopt;
  }
  const auto offset = searchOffset(pairs, samples, coarse->lowest, options.coarse_step_s,
                                   options.fine_step_s, options.max_gap_s, out.curve);
  const auto fit = offset ? fitAt(pairs, samples, offset->at, options.max_gap_s) : std::nullopt;
  if (!fit) {
    cannot(out, "the gyro's recording does not cover the pairs at offset " +
                    fixed(offset ? offset->at : coarse->lowest) + " s");
    return std::nullopt;
  }
  return Clock{*offset, *fit};
}

/// With a rolling shutter, after the first estimate from the images alone: the frame pairs
/// registered again with each row's rotation within its frame from the gyro at the current
/// estimate (the images alone cannot register a rolling-shutter frame as well: the rotation
/// rate changes within it), and the clock from them, kRounds times. Updates `pairs` and
/// `clock`; false (out.summary says why) when it cannot.
bool reclockRollingShutter(const Calibration& calibration, std::span<const cv::Mat> frames,
                           std::span<const double> times, std::span<const double> exposures,
                           std::span<const GyroSample> samples,
                           const ImuSearchOptions& options, std::vector<ImagePair>& pairs,
                           Clock& clock, ImuEstimate& out) {
  constexpr int kRounds = 4;
  Calibration c = calibration;
  for (int round = 0; round < kRounds; ++round) {
    c.imu = imuOf(clock);
    pairs = coveredPairs(imagePairs(c, frames, times, options.odometry, samples, exposures), samples,
                         options.max_offset_s, options.max_gap_s);
    if (static_cast<int>(pairs.size()) < kMinPairs)
      return cannot(out, std::to_string(pairs.size()) + " frame pairs tracked with the gyro's rows, at "
                         "least " + std::to_string(kMinPairs) + " needed");
    const auto next = searchClock(pairs, samples, options, out);
    if (!next) return false;
    clock = *next;
  }
  return true;
}

/// The clock offset, the mounting and a rolling shutter's readout from the pixels
/// (photometric_timing.hpp), starting from the pairs' clock and held to their mounting by its
/// uncertainty `mounting_sigma_deg` (measureUncertainty()). Nullopt when the pixels cannot
/// tell: the calibration's readout and the pairs' clock and mounting stay, and
/// out.pixels_summary says why.
std::optional<PhotometricTiming> measureTiming(const Calibration& calibration,
                                               std::span<const cv::Mat> frames,
                                               std::span<const double> times,
                                               std::span<const GyroSample> samples,
                                               const ImuSearchOptions& options, const Clock& clock,
                                               double mounting_sigma_deg, ImuEstimate& out) {
  Calibration c = calibration;
  c.imu = imuOf(clock);
  PhotometricTimingOptions pixels = options.pixels;
  pixels.max_gap_s = options.max_gap_s;
  const double mounting_sigma_rad = std::max(mounting_sigma_deg * std::numbers::pi / 180.0, 1e-5);
  const PhotometricTiming measured =
      refineTimingFromPixels(c, frames, times, samples, clock.fit.bias, mounting_sigma_rad, pixels);
  if (!measured.found) {
    out.pixels_summary =
        std::string(calibration.sensor.readout_s != 0.0 ? "the readout is the calibration's (" +
                                                              fixed(calibration.sensor.readout_s, 6) + " s), "
                                                        : "") +
        "the clock and the mounting the pairs', not measured from the pixels: " +
        measured.summary.substr(measured.summary.find(": ") + 2);
    return std::nullopt;
  }
  out.pixels_summary = "from the pixels: " + measured.summary;
  return measured;
}

/// `out` (its estimate and uncertainties measured) found, or refused with the reason when an
/// uncertainty exceeds what `options` allow; `axis_ratio` from measureUncertainty().
ImuEstimate judge(ImuEstimate out, double axis_ratio, const ImuSearchOptions& options) {
  char text[320];
  std::snprintf(text, sizeof(text),
                "%d pairs; rotation +-%.3f deg, time offset %+.5f s +-%.5f, bias (%+.5f, %+.5f, "
                "%+.5f) rad/s +-%.5f; residual %.3g rad per pair",
                out.pairs, out.rotation_sigma_deg, out.imu.time_offset_s, out.time_offset_sigma_s,
                out.bias.x(), out.bias.y(), out.bias.z(), out.bias_sigma.x(), out.residual_rms_rad);
  const std::string measured = text;
  // Why an estimate is uncertain: too little turn about some axis, or images and gyro that
  // disagree (a wrong readout or mounting of the frames' timestamps, motion the frames blur).
  std::snprintf(text, sizeof(text),
                "its weakest axis turns %.3g of its strongest (turn about at least two axes); the "
                "images and the gyro differ by %.3g rad per pair (a rolling shutter's readout "
                "wrong, or motion the frames cannot follow)",
                axis_ratio, out.residual_rms_rad);
  const std::string why = text;
  if (!(out.rotation_sigma_deg <= options.max_rotation_sigma_deg)) {
    cannot(out, "the mounting is not determined (" + measured + "); " + why);
    return out;
  }
  if (!(out.time_offset_sigma_s <= options.max_offset_sigma_s)) {
    cannot(out, "the clock offset is not determined (" + measured +
                    "): the recording must change its rate of turn; " + why);
    return out;
  }
  out.found = true;
  out.summary = measured;
  return out;
}

}  // namespace

std::vector<std::string> ImuSearchOptions::validate() const {
  std::vector<std::string> p;
  if (!(max_offset_s > 0.0 && max_offset_s <= ImuCalibration::kMaxTimeOffsetS))
    p.push_back("max_offset_s: must be in (0, " + fixed(ImuCalibration::kMaxTimeOffsetS, 1) + "] s");
  if (!(coarse_step_s > 0.0 && coarse_step_s <= max_offset_s))
    p.push_back("coarse_step_s: must be in (0, max_offset_s]");
  if (!(fine_step_s > 0.0 && fine_step_s <= coarse_step_s))
    p.push_back("fine_step_s: must be in (0, coarse_step_s]");
  if (!(max_rotation_sigma_deg > 0.0 && std::isfinite(max_rotation_sigma_deg)))
    p.push_back("max_rotation_sigma_deg: must be a finite number > 0");
  if (!(max_offset_sigma_s > 0.0 && std::isfinite(max_offset_sigma_s)))
    p.push_back("max_offset_sigma_s: must be a finite number > 0");
  if (!(max_gap_s > 0.0 && std::isfinite(max_gap_s)))
    p.push_back("max_gap_s: must be a finite number > 0");
  for (const auto& q : pixels.validate()) p.push_back("pixels." + q);
  for (const auto& q : odometry.validate()) p.push_back("odometry." + q);
  return p;
}

ImuEstimate estimateImuCalibration(const Calibration& calibration, std::span<const cv::Mat> frames,
                                   std::span<const double> times_s,
                                   std::span<const GyroSample> samples,
                                   const ImuSearchOptions& options,
                                   std::span<const double> exposures_s) {
  detail::throwIfProblems("estimateImuCalibration: invalid options", options.validate());
  if (frames.size() != times_s.size())
    throw std::invalid_argument("estimateImuCalibration: " + std::to_string(frames.size()) +
                                " frames but " + std::to_string(times_s.size()) + " times");
  if (!exposures_s.empty() && exposures_s.size() != frames.size())
    throw std::invalid_argument("estimateImuCalibration: " + std::to_string(frames.size()) +
                                " frames but " + std::to_string(exposures_s.size()) + " exposures");
  ImuEstimate out;
  const std::vector<ImagePair> tracked = imagePairs(calibration, frames, times_s, options.odometry);
  std::vector<ImagePair> pairs = coveredPairs(tracked, samples, options.max_offset_s, options.max_gap_s);
  out.pairs = static_cast<int>(pairs.size());
  if (out.pairs < kMinPairs) {
    cannot(out, std::to_string(tracked.size()) + " consecutive frame pairs tracked, " +
                    std::to_string(pairs.size()) + " of them inside the gyro's recording without a gap (+-" +
                    fixed(options.max_offset_s, 3) + " s), at least " + std::to_string(kMinPairs) +
                    " needed");
    return out;
  }
  auto clock = searchClock(pairs, samples, options, out);
  if (!clock) return out;
  if (calibration.sensor.readout_s != 0.0 &&
      !reclockRollingShutter(calibration, frames, times_s, exposures_s, samples, options, pairs,
                             *clock, out))
    return out;
  out.pairs = static_cast<int>(pairs.size());
  const double axis_ratio = measureUncertainty(pairs, clock->fit, clock->offset.curvature, out);
  const std::optional<PhotometricTiming> timing =
      measureTiming(calibration, frames, times_s, samples, options, *clock, out.rotation_sigma_deg, out);
  out.imu = imuOf(*clock);
  out.bias = clock->fit.bias;
  if (timing) {
    out.readout_s = timing->readout_s;
    out.readout_sigma_s = timing->readout_sigma_s;
    out.imu.time_offset_s = timing->time_offset_s;
    out.time_offset_sigma_s = timing->time_offset_sigma_s;
    out.imu.rotation = timing->rotation;
    out.rotation_sigma_deg = timing->rotation_sigma_deg;
  }
  return judge(out, axis_ratio, options);
}

}  // namespace omnipose::calibrate
