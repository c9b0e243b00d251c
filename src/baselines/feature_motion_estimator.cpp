#include "omnipose/baselines/feature_motion_estimator.hpp"

#include <chrono>
#include <cstdio>
#include <stdexcept>
#include <utility>

#include "common/problem_list.hpp"
#include "omnipose/so3.hpp"
#include "panorama_features.hpp"
#include "relative_pose_solver.hpp"

namespace omnipose::baselines {
namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

/// "field: must be ..., got X" with the value printed compactly.
std::string problem(const char* field, const char* rule, double value) {
  char buf[160];
  std::snprintf(buf, sizeof(buf), "%s: %s, got %g", field, rule, value);
  return buf;
}

/// RANSAC sample size of a solver in OpenGV (five-point: 5 + 3 for disambiguation).
int sampleSize(Solver solver) { return solver == Solver::kFivePoint ? 8 : 2; }

}  // namespace

const char* toString(Detector detector) {
  return detector == Detector::kOrb ? "orb" : "akaze";
}

const char* toString(Solver solver) {
  return solver == Solver::kFivePoint ? "five_point" : "rotation_only";
}

std::vector<std::string> FeatureMotionOptions::validate() const {
  std::vector<std::string> p;
  for (const auto& bad : unwrap.validate()) p.push_back("unwrap." + bad);
  if (max_features < 16 || max_features > 100000)
    p.push_back(problem("max_features", "must be in [16, 100000]", max_features));
  if (wrap_margin_px < 0 || wrap_margin_px > 256)
    p.push_back(problem("wrap_margin_px", "must be in [0, 256]", wrap_margin_px));
  if (orb_fast_threshold < 1 || orb_fast_threshold > 254)
    p.push_back(problem("orb_fast_threshold", "must be in [1, 254]", orb_fast_threshold));
  if (orb_patch_size < 7 || orb_patch_size > 63)
    p.push_back(problem("orb_patch_size", "must be in [7, 63]", orb_patch_size));
  if (orb_levels < 1 || orb_levels > 8)
    p.push_back(problem("orb_levels", "must be in [1, 8]", orb_levels));
  if (!(akaze_threshold > 0.0 && akaze_threshold < 1.0))
    p.push_back(problem("akaze_threshold", "must be in (0, 1)", akaze_threshold));
  if (akaze_octaves < 1 || akaze_octaves > 6)
    p.push_back(problem("akaze_octaves", "must be in [1, 6]", akaze_octaves));
  if (!(ratio > 0.0 && ratio <= 1.0)) p.push_back(problem("ratio", "must be in (0, 1]", ratio));
  if (!(threshold_px > 0.0 && threshold_px <= 100.0))
    p.push_back(problem("threshold_px", "must be in (0, 100] pixels", threshold_px));
  if (ransac_max_iterations < 1)
    p.push_back(problem("ransac_max_iterations", "must be >= 1", ransac_max_iterations));
  if (!(ransac_probability > 0.0 && ransac_probability < 1.0))
    p.push_back(problem("ransac_probability", "must be in (0, 1)", ransac_probability));
  if (min_inliers < sampleSize(solver)) {
    char rule[96];
    std::snprintf(rule, sizeof(rule), "must be >= %d (the %s RANSAC sample size)",
                  sampleSize(solver), toString(solver));
    p.push_back(problem("min_inliers", rule, min_inliers));
  }
  if (!(min_inlier_fraction >= 0.0 && min_inlier_fraction <= 1.0))
    p.push_back(problem("min_inlier_fraction", "must be in [0, 1]", min_inlier_fraction));
  return p;
}

std::string FeatureMotionOptions::methodName() const {
  return std::string(detector == Detector::kOrb ? "orb" : "akaze") +
         (solver == Solver::kFivePoint ? "5pt" : "rot");
}

std::optional<FeatureMotionOptions> FeatureMotionOptions::forMethod(std::string_view name) {
  for (Detector d : {Detector::kOrb, Detector::kAkaze}) {
    for (Solver s : {Solver::kFivePoint, Solver::kRotationOnly}) {
      FeatureMotionOptions o;
      o.detector = d;
      o.solver = s;
      if (o.methodName() == name) return o;
    }
  }
  return std::nullopt;
}

std::vector<std::string> FeatureMotionOptions::methodNames() {
  return {"orb5pt", "akaze5pt", "orbrot", "akazerot"};
}

struct FeatureMotionEstimator::Impl {
  Impl(const Calibration& c, const Options& o)
      : calibration(c),
        options(o),
        name(o.methodName()),
        unwrapper(c, o.unwrap),
        detector(o, c.panorama),
        panorama(unwrapper.makePanorama()) {
    settings.solver = o.solver;
    settings.threshold_rad = o.threshold_px * c.panorama.gamma();
    settings.max_iterations = o.ransac_max_iterations;
    settings.probability = o.ransac_probability;
    settings.refine = o.refine;
  }

  Calibration calibration;
  Options options;
  std::string name;
  Unwrapper unwrapper;
  PanoramaFeatureDetector detector;
  RelativePoseSettings settings;
  cv::Mat panorama;
  PanoramaFeatures previous, current;
  std::vector<std::pair<int, int>> matches;
  std::vector<Eigen::Vector3d> f_previous, f_current;
  bool has_previous = false;
};

FeatureMotionEstimator::FeatureMotionEstimator(const Calibration& calibration,
                                               const Options& options) {
  std::vector<std::string> problems = options.validate();
  for (const auto& p : calibration.validate()) problems.push_back("calibration: " + p);
  if (problems.empty() && options.wrap_margin_px > calibration.panorama.width)
    problems.push_back(problem("wrap_margin_px", "must not exceed the panorama width",
                               options.wrap_margin_px));
  detail::throwIfProblems("invalid " + options.methodName() + " configuration", problems);
  impl_ = std::make_unique<Impl>(calibration, options);
}

FeatureMotionEstimator::~FeatureMotionEstimator() = default;

void FeatureMotionEstimator::reset() {
  impl_->has_previous = false;
  impl_->previous.clear();
}

const char* FeatureMotionEstimator::name() const { return impl_->name.c_str(); }
const FeatureMotionOptions& FeatureMotionEstimator::options() const { return impl_->options; }
int FeatureMotionEstimator::lastKeypointCount() const {
  return static_cast<int>(impl_->previous.keypoints.size());
}

Expected<FrameMotion> FeatureMotionEstimator::process(const cv::Mat& frame) {
  Impl& s = *impl_;
  const auto t_start = Clock::now();
  FrameMotion result;

  // 1. Unwrap exactly as the pipeline does.
  if (auto ok = s.unwrapper.unwrap(frame, s.panorama); !ok) return std::unexpected(ok.error());
  result.timing.unwrap = secondsSince(t_start);

  // 2. Detect and describe the current frame (once; it is the next frame's previous).
  const auto t_features = Clock::now();
  try {
    s.detector.detect(s.panorama, s.current);
  } catch (const cv::Exception& e) {
    return fail(ErrorCode::kBadFrame, "%s: feature detection failed: %s", s.name.c_str(),
                e.what());
  }
  if (!s.has_previous) {
    std::swap(s.previous, s.current);
    s.has_previous = true;
    result.timing.registration = secondsSince(t_features);
    result.timing.total = secondsSince(t_start);
    return result;
  }

  // 3. Ratio-test matches previous -> current, as bearing pairs.
  matchRatioTest(s.previous, s.current, s.options.ratio, s.matches);
  s.f_previous.clear();
  s.f_current.clear();
  for (const auto& [i, j] : s.matches) {
    s.f_previous.push_back(s.previous.bearings[i]);
    s.f_current.push_back(s.current.bearings[j]);
  }
  result.timing.registration = secondsSince(t_features);

  // 4. RANSAC (+ refinement) on the bearings.
  const auto t_fit = Clock::now();
  MotionEstimate& est = result.estimate;
  est.windows_total = static_cast<int>(s.matches.size());
  est.status = FitStatus::kLost;
  if (est.windows_total >= s.options.min_inliers) {
    const RelativePoseResult pose = solveRelativePose(s.f_previous, s.f_current, s.settings);
    est.iterations = pose.iterations;
    est.windows_used = static_cast<int>(pose.inliers.size());
    if (pose.ok && est.windows_used >= s.options.min_inliers && pose.rotation.allFinite() &&
        pose.translation.allFinite()) {
      const double fraction = static_cast<double>(est.windows_used) / est.windows_total;
      est.status =
          fraction < s.options.min_inlier_fraction ? FitStatus::kDegraded : FitStatus::kOk;
      est.residual_rms_px = pose.residual_rms_rad / s.calibration.panorama.gamma();
      result.rotation = pose.rotation;
      est.omega = rotationVector(pose.rotation);
      if (s.options.solver == Solver::kFivePoint) {
        // Scale is unobservable: unit translation by convention (no rho for features).
        result.translation_direction = pose.translation;
        result.tau_norm = pose.translation.norm() > 0 ? 1.0 : 0.0;
        est.tau = pose.translation;
      }
    }
  }
  result.timing.fit = secondsSince(t_fit);

  // The current frame becomes the previous one, also after a lost pair.
  std::swap(s.previous, s.current);
  result.has_motion = true;
  result.timing.total = secondsSince(t_start);
  return result;
}

}  // namespace omnipose::baselines
