// omnipose-calibrate --checkerboard: the Mei model of a lens recovered by
// cv::omnidir from checkerboard views rendered exactly through a known Mei model.
#include "omnipose/calibrate/checkerboard.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Geometry>
#include <cmath>
#include <numbers>
#include <string>

#include "test_figures.hpp"

using ::testing::HasSubstr;

namespace omnipose::calibrate {
namespace {

constexpr double kPi = std::numbers::pi;

/// The lens every view is rendered through: a mirror camera, 800 x 800.
MeiModel trueLens() {
  MeiModel m;
  m.xi = 0.9;
  m.fx = 210.0;
  m.fy = 209.0;
  m.cx = 401.0;
  m.cy = 397.5;
  m.k1 = -0.03;
  m.k2 = 0.004;
  return m;
}

/// The pose of a board in omnidir's camera frame: rotation R (board to camera) and the
/// position t of its origin (a corner square).
struct BoardPose {
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
};

/// A 10 x 7-square board (9 x 6 inner corners, 4 cm squares) at each of `poses`, seen
/// through `lens`: each pixel's ray (unprojected by the model once for every pose) meets the
/// board plane; 3 x 3 sub-samples per pixel; grey 128 where no board is seen.
std::vector<cv::Mat> renderBoards(const MeiModel& lens, const std::vector<BoardPose>& poses) {
  constexpr double kSquare = 0.04;
  std::vector<cv::Mat> images(poses.size());
  for (cv::Mat& img : images) img.create(800, 800, CV_8UC1);
  std::vector<double> sums(poses.size());
  for (int y = 0; y < 800; ++y)
    for (int x = 0; x < 800; ++x) {
      std::fill(sums.begin(), sums.end(), 0.0);
      for (int j = 0; j < 3; ++j)
        for (int i = 0; i < 3; ++i) {
          const auto ray = lens.unproject({x + (i - 1) / 3.0, y + (j - 1) / 3.0});
          for (std::size_t k = 0; k < poses.size(); ++k) {
            const auto& [R, t] = poses[k];
            double v = 128;
            if (ray) {
              const Eigen::Vector3d n = R.col(2);  // board normal in the camera frame
              const double denom = n.dot(*ray);
              const double s = denom != 0 ? n.dot(t) / denom : -1;
              if (s > 0) {
                const Eigen::Vector3d local = R.transpose() * (s * *ray - t);  // board coordinates
                const double u = local.x() / kSquare + 1.0, w = local.y() / kSquare + 1.0;  // squares
                if (u >= 0 && u < 10 && w >= 0 && w < 7)
                  v = ((static_cast<int>(std::floor(u)) + static_cast<int>(std::floor(w))) % 2) ? 30 : 225;
              }
            }
            sums[k] += v;
          }
        }
      for (std::size_t k = 0; k < poses.size(); ++k)
        images[k].at<uchar>(y, x) = cv::saturate_cast<uchar>(sums[k] / 9);
    }
  return images;
}

/// Eight views around the camera (rendered once per process).
const std::vector<cv::Mat>& boardViews() {
  static const std::vector<cv::Mat> views = [] {
  std::vector<BoardPose> poses;
  // Boards 0.45 m away around the camera, near the horizon (mirror ring), facing it.
  for (int k = 0; k < 8; ++k) {
    const double az = 2 * kPi * k / 8 + 0.2;
    const double elev = (k % 3 - 1) * 0.12;  // -7 .. +7 deg; robot up is -z of omnidir
    const Eigen::Vector3d dir(std::cos(elev) * std::cos(az), std::cos(elev) * std::sin(az), -std::sin(elev));
    // Board frame: z towards the camera... its x along the horizontal tangent, y along -z.
    const Eigen::Vector3d z = -dir;
    const Eigen::Vector3d xa = Eigen::Vector3d::UnitZ().cross(z).normalized();
    const Eigen::Vector3d ya = z.cross(xa);
    Eigen::Matrix3d R;
    R.col(0) = xa;
    R.col(1) = ya;
    R.col(2) = z;
    R = R * Eigen::AngleAxisd(0.15 * (k % 2 ? 1 : -1), Eigen::Vector3d::UnitY()).toRotationMatrix();
    // Board centre on the viewing direction: t is the board origin (a corner square).
    const Eigen::Vector3d centre = 0.45 * dir;
    const Eigen::Vector3d t = centre - R * Eigen::Vector3d(0.16, 0.10, 0.0);
    poses.push_back({R, t});
  }
  return renderBoards(trueLens(), poses);
  }();
  return views;
}

TEST(Checkerboard, RecoversAMeiLensFromRenderedViews) {
  const MeiModel truth = trueLens();
  const std::vector<cv::Mat>& views = boardViews();
  CheckerboardOptions o;
  o.cols = 9;
  o.rows = 6;
  o.square_m = 0.04;
  const CheckerboardCalibration c = calibrateCheckerboard(views, o);
  std::string notes;
  for (const auto& n : c.notes) notes += (notes.empty() ? "" : "\n") + n;
  RecordProperty("notes", notes);
  SCOPED_TRACE("calibration notes:\n" + notes);
  EXPECT_GE(c.views_found, 6);
  EXPECT_LT(c.rms_px, 0.5);
  // Compare where the two models put the bearings of the ring (the parameters xi and f are
  // correlated; the mapping is what matters).
  double worst = 0;
  for (double elev = -0.3; elev <= 0.3; elev += 0.05)
    for (double a = 0; a < 2 * kPi; a += 0.3) {
      const auto p = truth.pixel(a, elev), q = c.model.pixel(a, elev);
      ASSERT_TRUE(p && q);
      worst = std::max(worst, (*p - *q).norm());
    }
  testing::recordFigure("max_pixel_difference_px", worst, 3);
  EXPECT_LT(worst, 1.0) << "largest pixel difference over elevations -17..17 deg, px";
}

// The whole --checkerboard path: a mei calibration.yaml the pipeline accepts.
TEST(Checkerboard, ImportWritesAValidMeiCalibration) {
  CheckerboardOptions board;
  board.square_m = 0.04;
  ModelImportOptions o;
  o.radius_inner = 100;
  o.radius_outer = 330;
  o.direction = AzimuthDirection::kCcw;
  const ModelImport r = importCheckerboard(boardViews(), board, o);
  EXPECT_EQ(r.calibration.omni.model, LensModelKind::kMei);
  ASSERT_TRUE(r.calibration.omni.mei);
  EXPECT_TRUE(r.calibration.validate().empty());
  EXPECT_EQ(r.calibration.omni.image_width, 800);
  const std::string yaml = r.calibration.toYaml();
  EXPECT_THAT(yaml, HasSubstr("model: mei"));
  EXPECT_NO_THROW(Calibration::parse(yaml, "checkerboard.yaml"));
}

TEST(Checkerboard, TooFewBoardsIsRefusedWithAHint) {
  const std::vector<cv::Mat> blank(3, cv::Mat(400, 400, CV_8UC1, cv::Scalar(128)));
  CheckerboardOptions o;
  try {
    calibrateCheckerboard(blank, o);
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_THAT(e.what(), HasSubstr("found in 0 image(s), need 3"));
  }
  EXPECT_THROW(parsePatternSize("9by6", o), std::invalid_argument);
  parsePatternSize("7x5", o);
  EXPECT_EQ(o.cols, 7);
  EXPECT_EQ(o.rows, 5);
}

}  // namespace
}  // namespace omnipose::calibrate
