#include "panorama_features.hpp"

#include <cmath>
#include <opencv2/imgproc.hpp>

namespace omnipose::baselines {

void PanoramaFeatures::clear() {
  keypoints.clear();
  descriptors.release();
  bearings.clear();
}

PanoramaFeatureDetector::PanoramaFeatureDetector(const FeatureMotionOptions& options,
                                                 const PanoramaGeometry& geometry)
    : options_(options), geometry_(geometry) {
  if (options.detector == Detector::kOrb) {
    // The padded image is wider than the panorama: ask for proportionally more keypoints,
    // the margins' duplicates are dropped after detection.
    const double widen =
        (geometry.width + 2.0 * options.wrap_margin_px) / static_cast<double>(geometry.width);
    feature_ = cv::ORB::create(static_cast<int>(std::ceil(options.max_features * widen)),
                               1.2f, options.orb_levels, options.orb_patch_size,
                               /*firstLevel=*/0, /*WTA_K=*/2, cv::ORB::HARRIS_SCORE,
                               options.orb_patch_size, options.orb_fast_threshold);
  } else {
    feature_ = cv::AKAZE::create(cv::AKAZE::DESCRIPTOR_MLDB, /*descriptor_size=*/0,
                                 /*descriptor_channels=*/3,
                                 static_cast<float>(options.akaze_threshold),
                                 options.akaze_octaves, /*nOctaveLayers=*/4,
                                 cv::KAZE::DIFF_PM_G2);
  }
}

void PanoramaFeatureDetector::detect(const cv::Mat& panorama, PanoramaFeatures& out) {
  out.clear();
  const int W = geometry_.width;
  const int margin = options_.wrap_margin_px;

  // 8-bit panorama (rounded, saturated), periodic in u: wrap columns into both margins.
  panorama.convertTo(grey_, CV_8U);
  cv::copyMakeBorder(grey_, padded_, 0, 0, margin, margin, cv::BORDER_WRAP);

  feature_->detect(padded_, candidates_);

  // Keep each keypoint once: its centre column (pixel centres at integers) in [0, W).
  std::erase_if(candidates_, [&](const cv::KeyPoint& k) {
    const double column = std::floor(k.pt.x + 0.5) - margin;
    return column < 0 || column >= W;
  });
  cv::KeyPointsFilter::retainBest(candidates_, options_.max_features);

  // Describe on the padded image (descriptors see the true neighbourhood across the seam).
  feature_->compute(padded_, candidates_, out.descriptors);
  out.keypoints = candidates_;

  // Bearings of the panorama model (DESIGN.md section 2).
  out.bearings.reserve(out.keypoints.size());
  for (cv::KeyPoint& k : out.keypoints) {
    k.pt.x -= static_cast<float>(margin);
    out.bearings.push_back(geometry_.bearing(k.pt.x, k.pt.y));
  }
}

void matchRatioTest(const PanoramaFeatures& previous, const PanoramaFeatures& current, double ratio,
                    std::vector<std::pair<int, int>>& matches) {
  matches.clear();
  if (previous.descriptors.empty() || current.descriptors.rows < 2) return;
  cv::BFMatcher matcher(cv::NORM_HAMMING, /*crossCheck=*/false);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(previous.descriptors, current.descriptors, knn, 2);
  for (const auto& m : knn) {
    if (m.size() == 2 && m[0].distance < ratio * m[1].distance)
      matches.emplace_back(m[0].queryIdx, m[0].trainIdx);
  }
}

}  // namespace omnipose::baselines
