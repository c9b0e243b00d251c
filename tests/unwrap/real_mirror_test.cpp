// The real mirror image of tests/data/catadioptric unwrapped with its OCamCalib file:
// vertical building edges must come out vertical in the panorama.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "omnipose/calibration.hpp"
#include "omnipose/unwrapper.hpp"
#include "test_figures.hpp"

namespace omnipose {
namespace {

const std::filesystem::path kData =
    std::filesystem::path(OMNIPOSE_SOURCE_DIR) / "tests/data/catadioptric";

/// Slant from vertical (degrees) of every long, near-vertical edge of a panorama: pixels
/// with a strong horizontal gradient (|gx| > 120 and > 3 |gy|, per gradient sign) are
/// grouped into connected components; each component at least 40 rows tall and at most a
/// third as wide is fitted by x = a + b y through its gradient-weighted row centroids.
std::vector<double> verticalEdgeSlantsDeg(const cv::Mat& panorama) {
  cv::Mat g, gx, gy;
  cv::GaussianBlur(panorama, g, {0, 0}, 1.0);
  cv::Sobel(g, gx, CV_32F, 1, 0);
  cv::Sobel(g, gy, CV_32F, 0, 1);
  std::vector<double> slants;
  for (const float sign : {1.0f, -1.0f}) {
    cv::Mat edge(g.size(), CV_8U, cv::Scalar(0));
    for (int y = 0; y < g.rows; ++y)
      for (int x = 0; x < g.cols; ++x) {
        const float a = sign * gx.at<float>(y, x), b = gy.at<float>(y, x);
        if (a > 120 && a > 3 * std::abs(b)) edge.at<uchar>(y, x) = 255;
      }
    cv::Mat labels, stats, centroids;
    const int n = cv::connectedComponentsWithStats(edge, labels, stats, centroids, 8);
    for (int k = 1; k < n; ++k) {
      const int top = stats.at<int>(k, cv::CC_STAT_TOP), left = stats.at<int>(k, cv::CC_STAT_LEFT);
      const int h = stats.at<int>(k, cv::CC_STAT_HEIGHT), w = stats.at<int>(k, cv::CC_STAT_WIDTH);
      if (h < 40 || w > h / 3) continue;
      double sy = 0, sx = 0, syy = 0, sxy = 0, count = 0;
      for (int y = top; y < top + h; ++y) {
        double weight = 0, moment = 0;
        for (int x = left; x < left + w; ++x) {
          if (labels.at<int>(y, x) != k) continue;
          weight += sign * gx.at<float>(y, x);
          moment += sign * gx.at<float>(y, x) * x;
        }
        if (weight <= 0) continue;
        const double xc = moment / weight;
        sy += y, sx += xc, syy += double(y) * y, sxy += y * xc, count += 1;
      }
      if (count < 30) continue;
      const double slope = (count * sxy - sy * sx) / (count * syy - sy * sy);
      slants.push_back(std::atan(slope) * 180.0 / CV_PI);
    }
  }
  return slants;
}

struct SlantSummary {
  std::size_t edges = 0;
  double median = 0, p75 = 0;
};

SlantSummary unwrapAndMeasure(double centre_shift_px) {
  Calibration c = Calibration::parse(
      "omni:\n  model: ocamcalib\n  ocamcalib_file: mirror_office_ocamcalib.txt\n"
      "  azimuth_direction: ccw\npanorama: {width: 1440, height: 240, horizon_row: 100}\n",
      "office.yaml", kData);
  c.omni.ocamcalib->xc += centre_shift_px;
  c.omni.ocamcalib->yc += centre_shift_px;
  const cv::Mat image =
      cv::imread((kData / "mirror_office_1920x1080.jpg").string(), cv::IMREAD_GRAYSCALE);
  Unwrapper unwrapper(c, {});
  cv::Mat panorama = unwrapper.makePanorama();
  EXPECT_TRUE(unwrapper.unwrap(image, panorama));
  std::vector<double> a;
  for (double s : verticalEdgeSlantsDeg(panorama)) a.push_back(std::abs(s));
  std::sort(a.begin(), a.end());
  if (a.empty()) return {};
  return {a.size(), a[a.size() / 2], a[a.size() * 3 / 4]};
}

TEST(RealMirror, VerticalEdgesAreVerticalWithItsOcamCalibFile) {
  const SlantSummary right = unwrapAndMeasure(0.0);
  RecordProperty("vertical_edges", static_cast<int>(right.edges));
  testing::recordFigure("slant_median_deg", right.median, 2);
  testing::recordFigure("slant_p75_deg", right.p75, 2);
  ASSERT_GE(right.edges, 12u);
  EXPECT_LT(right.median, 2.5);
  EXPECT_LT(right.p75, 3.5);
  // The measure sees a wrong axis: 40 px off in x and y slants the same edges clearly.
  const SlantSummary wrong = unwrapAndMeasure(-40.0);
  RecordProperty("centre_40px_off_vertical_edges", static_cast<int>(wrong.edges));
  testing::recordFigure("centre_40px_off_slant_median_deg", wrong.median, 2);
  testing::recordFigure("centre_40px_off_slant_p75_deg", wrong.p75, 2);
  EXPECT_GT(wrong.median, right.median + 1.5) << "|slant| median with the centre 40 px off";
}

// Where the ring leaves the 1920 x 1080 frame (top of the outer ring) the panorama has no
// data: the unwrapper marks it unusable instead of passing black off as scene.
TEST(RealMirror, PixelsOutsideTheFrameAreMarkedUnusable) {
  const Calibration c = Calibration::parse(
      "omni:\n  model: ocamcalib\n  ocamcalib_file: mirror_office_ocamcalib.txt\n"
      "panorama: {width: 1440, height: 240, horizon_row: 100}\n",
      "office.yaml", kData);
  Unwrapper unwrapper(c, {});
  EXPECT_GT(unwrapper.usableFraction(), 0.9);
  EXPECT_LT(unwrapper.usableFraction(), 0.995);
  // Row 0 (elevation +24 deg, radius ~580 px) leaves the frame above and below the centre.
  const cv::Mat& valid = unwrapper.validity();
  double row0 = 0;
  for (int u = 0; u < valid.cols; ++u) row0 += valid.at<float>(0, u);
  EXPECT_LT(row0 / valid.cols, 0.95);
}

}  // namespace
}  // namespace omnipose
