#pragma once
// Keypoints, descriptors and bearings of one panorama (private to omnipose_baselines).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>
#include <vector>

#include "omnipose/baselines/feature_motion_estimator.hpp"
#include "omnipose/calibration.hpp"

namespace omnipose::baselines {

/// The features of one frame: keypoint i has descriptor row i and bearing i.
struct PanoramaFeatures {
  std::vector<cv::KeyPoint> keypoints;  ///< panorama pixels, u in [0, W)
  cv::Mat descriptors;                  ///< one binary descriptor per row (CV_8U)
  std::vector<Eigen::Vector3d> bearings;  ///< unit bearings, camera frame

  void clear();
};

/// Detects ORB or AKAZE features on a periodic panorama. Detection runs on the 8-bit
/// panorama with `wrap_margin_px` columns of the opposite end copied to each side, so a
/// feature that straddles u = 0 is found and described from its true neighbourhood; each
/// keypoint is kept once, where its centre lies in [0, W).
class PanoramaFeatureDetector {
 public:
  /// Options must be valid (FeatureMotionOptions::validate()).
  PanoramaFeatureDetector(const FeatureMotionOptions& options, const PanoramaGeometry& geometry);

  /// Features of `panorama` (CV_32FC1, grey 0..255, W x H) into `out`.
  void detect(const cv::Mat& panorama, PanoramaFeatures& out);

 private:
  FeatureMotionOptions options_;
  PanoramaGeometry geometry_;
  cv::Ptr<cv::Feature2D> feature_;
  cv::Mat grey_, padded_;
  std::vector<cv::KeyPoint> candidates_;
};

/// Lowe ratio-test matches from `previous` to `current`: (index in previous, index in
/// current) pairs whose best Hamming distance is below ratio * the second best.
void matchRatioTest(const PanoramaFeatures& previous, const PanoramaFeatures& current, double ratio,
                    std::vector<std::pair<int, int>>& matches);

}  // namespace omnipose::baselines
