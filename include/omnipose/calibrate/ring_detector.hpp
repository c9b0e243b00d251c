#pragma once
/// \file ring_detector.hpp
/// Finds the used ring of an omni donut: the mirror axis (centre) and the radii where the
/// scene begins (inner: the dark centre / camera reflection ends) and ends (outer: the lens
/// body begins), from one image.
///
/// Steps (each pass re-centres on the previous result):
///  1. Coarse centre: every strong gradient pixel of a downscaled copy votes along its
///     gradient line (both ways, Hough-style); all the concentric edges of the lens body
///     and the ring meet at the axis, scene edges spread out. Peak of the smoothed votes.
///  2. Polar resampling about the centre: P(theta_i, r), `rays` rays, `radial_step` px.
///  3. Ring interval (first pass): the scene varies along the circle, the lens body does
///     not (its edges are circles). The tangential texture profile
///     t(r) = mean_i |P(theta_i+k, r) - P(theta_i-k, r)| (k: ~3 px of arc) is high on the
///     ring; the coarse ring [r_in0, r_out0] is the radius interval maximising
///     sum (t(r) - tau), tau = lo + 0.25 (hi - lo) from the profile's 10 % / 90 % quantiles
///     (maximum subarray: low-texture bands of the scene such as sky or paving stay in when
///     textured radii on both sides outweigh them).
///  3b. A textureless band of the scene at a ring edge (ceiling, sky, floor) ends the
///     texture interval inside the ring; the ring's edges are the strongest steps that are
///     coherent across the rays (M(r) = median over rays of dP/dr), so a boundary moves onto
///     a coherent step beyond the interval that is twice as strong as any about it.
///  4. Per ray, the edge is the extreme of the radial derivative dP/dr (Gaussian-smoothed)
///     inside a window about each coarse boundary, in the dominant polarity when most rays
///     agree (e.g. scene -> dark body), sub-pixel by a parabola through the peak.
///  5. Each boundary: RANSAC circle fit (MSAC), Taubin algebraic then geometric least
///     squares on the inliers; then both rings together as two concentric circles (one
///     centre, two radii), which is the model the calibration uses.
///  6. Stacked edges: the strongest edge is not always the last one of the lens body (a
///     phone camera's reflection is a dark lens inside a bright bezel). Just inside the
///     ring (a band of `stack_band_fraction` of the radius beyond the edge) a further edge
///     that is coherent across the rays - a local extreme of the median over all rays of
///     dP/dr of at least `stack_min_contrast` of the edge's own - is lens body too: the
///     boundary moves onto it (up to 3 times). Scene edges do not survive the median.
///
/// Radii reported here are the edges themselves; the calibration shrinks the ring by a
/// safety margin (see lens_calibrator.hpp).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "omnipose/calibrate/circle_fit.hpp"
#include "omnipose/error.hpp"

namespace omnipose::calibrate {

struct RingDetectorOptions {
  int rays = 1024;             ///< rays of the polar resampling (one edge point per ray)
  double radial_step = 0.5;    ///< radial sample spacing, pixels
  double edge_sigma = 1.0;     ///< radial Gaussian smoothing before the derivative, pixels
  int vote_size = 480;         ///< longer side of the downscaled voting image, pixels
  /// Use this as the coarse centre instead of voting (pixels, full resolution).
  std::optional<Eigen::Vector2d> center_guess;
  /// Keep the centre fixed (only the radii are fitted).
  std::optional<Eigen::Vector2d> fixed_center;
  /// Hints for the coarse boundaries (pixels); they replace the texture profile's guess.
  std::optional<double> inner_guess;
  std::optional<double> outer_guess;
  double min_radius = 5.0;          ///< smallest ring radius considered, pixels
  std::optional<double> max_radius; ///< largest; default: the farthest image corner
  /// First-pass search window about each coarse boundary, +- this fraction of its radius
  /// (but at least 6 px).
  double search_fraction = 0.08;
  /// A radius counts in the texture profile when at least this fraction of the rays lies
  /// inside the image (donuts cut by the image border).
  double min_valid_fraction = 0.25;
  int passes = 3;                   ///< polar resampling / fit passes (>= 1)
  double inlier_threshold = 1.5;    ///< RANSAC inlier distance, pixels
  bool stacked_edges = true;        ///< step 6 on/off
  double stack_band_fraction = 0.08;
  double stack_min_contrast = 0.3;  ///< median dP/dr relative to the edge it replaces
  std::uint64_t seed = 1;

  /// Empty when valid, else one message per bad field.
  std::vector<std::string> validate() const;
};

/// One boundary of the ring (inner or outer).
struct RingEdge {
  Circle circle;                        ///< independent RANSAC + least-squares fit
  std::vector<Eigen::Vector2d> points;  ///< edge points found (at most one per ray)
  std::vector<int> inliers;             ///< indices into points
  double rms = 0.0;                     ///< RMS distance of the inliers to `circle`, pixels
  double inlier_fraction = 0.0;         ///< inliers / rays
  int polarity = 0;       ///< +1: brighter outside the edge, -1: darker outside, 0: mixed
  double width = 0.0;     ///< edge transition std (blur), pixels
  double contrast = 0.0;  ///< median step height across the edge, grey levels
  int stacked = 0;           ///< step 6: how many further concentric edges it moved past
  double first_radius = 0.0; ///< radius of the first (strongest) edge before step 6
};

/// Result for one image.
struct RingDetection {
  cv::Size image_size;
  Eigen::Vector2d coarse_center = Eigen::Vector2d::Zero();  ///< voting (or guess)
  double coarse_inner = 0.0;   ///< texture-profile boundaries (after step 3b), pixels
  double coarse_outer = 0.0;
  /// Step 3b moved the boundary onto a stronger coherent step beyond the texture interval
  /// (a textureless band of the scene at that edge).
  bool inner_moved_to_step = false;
  bool outer_moved_to_step = false;
  Eigen::Vector2d center = Eigen::Vector2d::Zero();  ///< concentric fit, pixels
  double radius_inner = 0.0;   ///< edge radii of the concentric fit, pixels
  double radius_outer = 0.0;
  double rms = 0.0;            ///< RMS distance of all inliers to the concentric circles
  RingEdge inner;
  RingEdge outer;
  /// t(r) of step 3 at r = k * radial_step (NaN where too few rays are inside the image).
  std::vector<double> texture_profile;
  double radial_step = 0.5;
};

/// Detects the ring in one image (8-bit grey/BGR/BGRA or 32-bit float grey).
/// Errors: kInvalidArgument (options, empty image), kIllConditioned (no ring interval or too
/// few edge points for a circle).
Expected<RingDetection> detectRing(const cv::Mat& image, const RingDetectorOptions& options);

/// Coarse centre of the concentric edges (step 1 only), full-resolution pixels.
Eigen::Vector2d voteCenter(const cv::Mat& grey, int vote_size);

/// Several images of one lens combined: per-value median, with the largest deviation of a
/// frame from it (a lens does not move against the camera, so this is the repeatability).
struct RingEstimate {
  Eigen::Vector2d center = Eigen::Vector2d::Zero();
  double radius_inner = 0.0;
  double radius_outer = 0.0;
  double center_spread = 0.0;  ///< max |c_k - c|, pixels
  double inner_spread = 0.0;   ///< max |r_k - r|, pixels
  double outer_spread = 0.0;
  double edge_width_inner = 0.0;  ///< median edge blur std, pixels
  double edge_width_outer = 0.0;
  double first_inner = 0.0;       ///< median radius of the strongest edges before step 6
  double first_outer = 0.0;
  int stacked_inner = 0;          ///< step 6 moves (of the first detection)
  int stacked_outer = 0;
  int frames = 0;
};
/// Per-value median of the detections. Throws std::invalid_argument on an empty list.
RingEstimate combineDetections(std::span<const RingDetection> detections);

/// Several frames of one lens: steps 1-5 on each frame, the per-value median, then step 6
/// on all frames together (pooled rays) about the median centre, so the frames agree on
/// which edge bounds the ring.
struct MultiRingDetection {
  std::vector<RingDetection> detections;  ///< of the frames where steps 1-5 succeeded
  std::vector<std::string> errors;        ///< per input frame, empty = detected
  std::optional<RingEstimate> estimate;   ///< empty when no frame was detected
};
MultiRingDetection detectRings(std::span<const cv::Mat> frames, const RingDetectorOptions& options);

/// Converts an 8-bit grey/BGR/BGRA or float image to CV_32FC1 grey levels 0..255.
cv::Mat toGreyFloat(const cv::Mat& image);

}  // namespace omnipose::calibrate
