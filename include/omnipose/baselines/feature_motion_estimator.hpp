#pragma once
/// \file feature_motion_estimator.hpp
/// Feature-based baselines of the paper's evaluation (Table I), as MotionEstimators that
/// replay, evaluation and the benchmark treat like the iFMI pipeline:
///
///   unwrap (same Unwrapper as the pipeline) -> 8-bit panorama, padded by wrapping columns
///   -> ORB or AKAZE keypoints + binary descriptors (each frame detected once; the previous
///      frame's keypoints and descriptors are kept)
///   -> brute-force Hamming 2-NN matching previous -> current, Lowe ratio test
///   -> bearings f = PanoramaGeometry::bearing(u, v) (DESIGN.md section 2)
///   -> OpenGV RANSAC: Stewenius 5-point (+ nonlinear refinement on the inliers), or
///      2-point rotation-only (+ least-squares rotation on the inliers)
///
/// Conventions. OpenGV's relative pose (R12, t12) maps frame-2 coordinates into frame 1:
/// P_1 = R12 P_2 + t12 (rotation only: f_1 ~ R12 f_2). With frame 1 = previous and frame 2
/// = current this is exactly DESIGN.md's (R, t) with P_{k-1} = R P_k + t, so no conversion
/// is needed; tests/baselines proves it on rendered +-3 deg yaw and forward motion.
///
/// Angular inlier threshold: `threshold_px` panorama pixels, i.e. an angle
/// alpha = threshold_px * gamma (gamma = 2 pi / W), passed to OpenGV as 1 - cos(alpha).
///
/// What FrameMotion carries for a feature method:
///   rotation, estimate.omega       R and its rotation vector
///   translation_direction, tau_norm  five_point: t/|t| and 1 (the scale is unobservable,
///                                    there is no rho); rotation_only: 0 and 0
///   estimate.tau                   translation_direction * tau_norm
///   estimate.windows_used / _total RANSAC inliers / ratio-test matches
///   estimate.residual_rms_px       RMS angular residual of the inliers, panorama pixels
///                                  (five_point: distance to the epipolar plane)
///   estimate.iterations            RANSAC iterations
///   estimate.status                kLost when there are fewer than min_inliers matches or
///                                  inliers (or RANSAC finds no model); kDegraded when the
///                                  inlier fraction is below min_inlier_fraction
///   timing                         unwrap; registration = detect + describe + match;
///                                  fit = RANSAC + refinement; total
///
/// Unlike the pipeline, process() allocates (OpenCV feature code does): these are
/// evaluation baselines, not the onboard path. Not thread-safe: one instance per thread.

#include <memory>
#include <optional>
#include <opencv2/core.hpp>
#include <string>
#include <string_view>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/error.hpp"
#include "omnipose/motion_estimator.hpp"
#include "omnipose/unwrapper.hpp"

namespace omnipose::baselines {

/// Keypoint detector and descriptor (OpenCV features2d).
enum class Detector {
  kOrb,    ///< oriented FAST + rotated BRIEF, 256-bit
  kAkaze,  ///< AKAZE with MLDB descriptors (486-bit)
};

/// Relative-pose solver inside RANSAC (OpenGV).
enum class Solver {
  kFivePoint,     ///< Stewenius 5-point essential matrix + nonlinear refinement (paper)
  kRotationOnly,  ///< 2-point rotation-only (exact for pure rotation)
};

const char* toString(Detector detector);
const char* toString(Solver solver);

struct FeatureMotionOptions {
  /// Input kind and black-frame threshold, as for the pipeline.
  Unwrapper::Options unwrap;
  Detector detector = Detector::kOrb;
  Solver solver = Solver::kFivePoint;

  // --- features ---------------------------------------------------------------------------
  /// At most this many keypoints per frame (the strongest by detector response).
  int max_features = 2000;
  /// Columns copied from the other end on each side before detection, so features across
  /// the u = 0 seam are found; keypoints are kept once, in [0, W). Pixels.
  int wrap_margin_px = 48;
  /// ORB: FAST threshold (grey levels), patch size and border (pixels), pyramid levels.
  /// The paper's 1100 x 110 panorama is short: OpenCV's default 31-pixel patch and border
  /// would leave only the middle 48 rows.
  int orb_fast_threshold = 12;
  int orb_patch_size = 19;
  int orb_levels = 4;
  /// AKAZE: detector response threshold (OpenCV default 0.001) and octaves.
  double akaze_threshold = 0.0005;
  int akaze_octaves = 3;

  // --- matching ---------------------------------------------------------------------------
  /// Lowe ratio test: keep a match when best distance < ratio * second-best distance.
  double ratio = 0.8;

  // --- robust estimation ------------------------------------------------------------------
  /// Angular inlier threshold, panorama pixels (alpha = threshold_px * 2 pi / W).
  double threshold_px = 1.0;
  int ransac_max_iterations = 1000;
  double ransac_probability = 0.999;
  /// Fewer ratio-test matches or RANSAC inliers than this: status kLost.
  int min_inliers = 12;
  /// Inlier fraction below this: status kDegraded.
  double min_inlier_fraction = 0.25;
  /// five_point: nonlinear refinement (OpenGV optimize_nonlinear) on the inliers;
  /// rotation_only: least-squares rotation on the inliers.
  bool refine = true;

  /// Every problem, one message per bad field, each starting with the field name
  /// (empty = valid).
  std::vector<std::string> validate() const;

  /// The method name of this detector/solver pair: orb5pt, akaze5pt, orbrot, akazerot.
  std::string methodName() const;
  /// Options of a named method (defaults otherwise), or nullopt for an unknown name.
  static std::optional<FeatureMotionOptions> forMethod(std::string_view name);
  /// The four method names forMethod() accepts.
  static std::vector<std::string> methodNames();
};

/// A feature-based frame-to-frame motion estimator (see the file comment).
class FeatureMotionEstimator final : public MotionEstimator {
 public:
  using Options = FeatureMotionOptions;

  /// Throws std::invalid_argument listing every invalid option (by field name) or
  /// calibration field.
  FeatureMotionEstimator(const Calibration& calibration, const Options& options);
  ~FeatureMotionEstimator() override;
  FeatureMotionEstimator(const FeatureMotionEstimator&) = delete;
  FeatureMotionEstimator& operator=(const FeatureMotionEstimator&) = delete;

  /// Motion of `frame` (8-bit grey/BGR/BGRA, omni or panorama per options().unwrap)
  /// relative to the previous good frame. First frame after start/reset: has_motion false.
  /// A rejected frame (kBadFrame) leaves the state untouched. After a lost pair the current
  /// frame still becomes the previous one (as in the pipeline).
  Expected<FrameMotion> process(const cv::Mat& frame) override;
  void reset() override;
  /// "orb5pt", "akaze5pt", "orbrot" or "akazerot".
  const char* name() const override;

  const Options& options() const;
  /// Keypoints of the last good frame (panorama pixels, u in [0, W)).
  int lastKeypointCount() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace omnipose::baselines
