#pragma once
/// \file ring_checks.hpp
/// Quality gates of the ring detection (`omnipose-calibrate` refuses instead of writing a
/// calibration that is silently wrong):
///  - support: each edge fitted to at least `min_inlier_fraction` of the rays that lie
///    inside the image;
///  - agreement: the frames' centres and radii agree with their median;
///  - motion (3 or more frames of a moving robot): the scene moves inside the ring and the
///    lens body does not, so scene motion just outside the outer edge or just inside the
///    inner edge means the edge was found inside the ring (a scene edge that is a circle,
///    such as a dark floor or a horizon); and an edge of weak contrast with nothing moving
///    next to it inside the ring cannot be told from the lens body.

#include <opencv2/core.hpp>
#include <span>
#include <string>
#include <vector>

#include "omnipose/calibrate/ring_detector.hpp"

namespace omnipose::calibrate {

struct RingCheckOptions {
  double min_inlier_fraction = 0.3;  ///< of the rays inside the image, per edge and frame
  double max_center_spread = 1.0;    ///< pixels, a frame's centre from the median
  double max_radius_spread = 2.0;    ///< pixels, a frame's radius from the median
  /// A radius "moves" when its mean squared frame-to-frame change exceeds the sensor noise's
  /// (the 10 % quantile over all radii: the lens body is still) by this factor.
  double motion_noise_factor = 3.0;
  /// Band checked beside each edge, pixels beyond 2 x the edge blur + 3 px.
  double band_px = 12.0;
  /// An edge weaker than this many sensor-noise sigmas needs motion beside it.
  double weak_edge_sigmas = 10.0;
};

struct RingCheck {
  std::vector<std::string> refusals;  ///< empty = passed; each names the reason and what to try
  std::vector<std::string> notes;     ///< what was checked (or why the motion check could not run)
};

/// Checks a combined ring estimate and its per-frame detections against the frames.
RingCheck checkRing(std::span<const cv::Mat> frames, const RingEstimate& ring,
                    std::span<const RingDetection> detections, const RingCheckOptions& options = {});

}  // namespace omnipose::calibrate
