#include "omnipose/calibrate/checkerboard.hpp"

#include "omnipose/calibrate/ring_detector.hpp"

#include <cstdio>
#include <opencv2/calib3d.hpp>
#include <opencv2/ccalib/omnidir.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace omnipose::calibrate {

void parsePatternSize(const std::string& text, CheckerboardOptions& o) {
  int c = 0, r = 0;
  char x = 0, extra = 0;
  if (std::sscanf(text.c_str(), "%d%c%d%c", &c, &x, &r, &extra) != 3 || (x != 'x' && x != 'X') ||
      c < 2 || r < 2 || c > 100 || r > 100)
    throw std::invalid_argument("'" + text + "' is not COLSxROWS inner corners (each 2..100), e.g. 9x6");
  o.cols = c;
  o.rows = r;
}

CheckerboardCalibration calibrateCheckerboard(std::span<const cv::Mat> images,
                                              const CheckerboardOptions& o) {
  if (!(o.square_m > 0 && o.square_m < 10))
    throw std::runtime_error("--square: the side of a square must be in (0, 10) metres");
  if (images.empty()) throw std::runtime_error("--checkerboard: no images");
  const cv::Size pattern(o.cols, o.rows), size = images.front().size();
  std::vector<cv::Vec3d> board;
  for (int r = 0; r < o.rows; ++r)
    for (int c = 0; c < o.cols; ++c) board.emplace_back(c * o.square_m, r * o.square_m, 0.0);

  CheckerboardCalibration out;
  std::vector<cv::Mat> object_points, image_points;
  std::string missing;
  for (std::size_t k = 0; k < images.size(); ++k) {
    if (images[k].size() != size)
      throw std::runtime_error("--checkerboard: image " + std::to_string(k) + " differs in size");
    cv::Mat grey;
    if (images[k].channels() == 1) grey = images[k];
    else cv::cvtColor(images[k], grey, cv::COLOR_BGR2GRAY);
    std::vector<cv::Point2f> corners;
    const bool found = cv::findChessboardCorners(
        grey, pattern, corners, cv::CALIB_CB_ADAPTIVE_THRESH | cv::CALIB_CB_NORMALIZE_IMAGE);
    if (!found) {
      missing += " " + std::to_string(k);
      continue;
    }
    cv::cornerSubPix(grey, corners, {5, 5}, {-1, -1},
                     cv::TermCriteria(cv::TermCriteria::EPS + cv::TermCriteria::COUNT, 50, 1e-3));
    cv::Mat pts(1, static_cast<int>(corners.size()), CV_64FC2);
    for (std::size_t i = 0; i < corners.size(); ++i) pts.at<cv::Vec2d>(0, static_cast<int>(i)) = cv::Vec2d(corners[i].x, corners[i].y);
    image_points.push_back(pts);
    object_points.push_back(cv::Mat(board, true).reshape(3, 1));
  }
  out.views_found = static_cast<int>(image_points.size());
  out.notes.push_back("board " + std::to_string(o.cols) + "x" + std::to_string(o.rows) +
                      " found in " + std::to_string(out.views_found) + " of " +
                      std::to_string(images.size()) + " images" +
                      (missing.empty() ? "" : " (not in image" + missing + ")"));
  if (out.views_found < o.min_views)
    throw std::runtime_error("--checkerboard: the " + std::to_string(o.cols) + "x" +
                             std::to_string(o.rows) + " board was found in " +
                             std::to_string(out.views_found) + " image(s), need " +
                             std::to_string(o.min_views) +
                             "; try more views spread around the ring, check COLSxROWS (inner "
                             "corners), or keep the board flat and well lit");
  cv::Mat K, xi, D, idx;
  std::vector<cv::Mat> rvecs, tvecs;
  try {
    out.rms_px = cv::omnidir::calibrate(
        object_points, image_points, size, K, xi, D, rvecs, tvecs, cv::omnidir::CALIB_FIX_SKEW,
        cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 300, 1e-8), idx);
  } catch (const cv::Exception& e) {
    throw std::runtime_error("--checkerboard: cv::omnidir::calibrate failed: " + e.msg);
  }
  out.views_used = static_cast<int>(idx.total());
  if (K.empty() || xi.empty() || D.empty() || !std::isfinite(out.rms_px))
    throw std::runtime_error("--checkerboard: cv::omnidir::calibrate gave no model; try more views");
  K.convertTo(K, CV_64F);
  D.convertTo(D, CV_64F);
  xi.convertTo(xi, CV_64F);
  MeiModel& m = out.model;
  m.xi = xi.at<double>(0);
  m.fx = K.at<double>(0, 0);
  m.s = K.at<double>(0, 1);
  m.cx = K.at<double>(0, 2);
  m.fy = K.at<double>(1, 1);
  m.cy = K.at<double>(1, 2);
  const double* d = D.ptr<double>();
  m.k1 = d[0], m.k2 = d[1], m.p1 = d[2], m.p2 = d[3];
  if (const auto p = m.validate(); !p.empty())
    throw std::runtime_error("--checkerboard: the calibrated model is not usable: " + p.front());
  char buf[200];
  std::snprintf(buf, sizeof buf, "Mei model from %d views: xi %.4f, f %.2f / %.2f px, centre (%.2f, %.2f), "
                "reprojection error %.3f px RMS", out.views_used, m.xi, m.fx, m.fy, m.cx, m.cy, out.rms_px);
  out.notes.push_back(buf);
  return out;
}

ModelImport importCheckerboard(std::span<const cv::Mat> images, const CheckerboardOptions& board,
                                   const ModelImportOptions& options) {
  const CheckerboardCalibration cb = calibrateCheckerboard(images, board);
  ModelImport out;
  out.notes = cb.notes;
  Calibration& c = out.calibration;
  OmniLens& lens = c.omni;
  lens.model = LensModelKind::kMei;
  lens.mei = cb.model;
  lens.image_width = images.front().cols;
  lens.image_height = images.front().rows;
  lens.center_x = cb.model.cx;
  lens.center_y = cb.model.cy;
  if (options.radius_inner && options.radius_outer) {
    lens.radius_inner = *options.radius_inner;
    lens.radius_outer = *options.radius_outer;
    out.notes.push_back("ring as given");
  } else {
    RingDetectorOptions ro;
    ro.fixed_center = Eigen::Vector2d(cb.model.cx, cb.model.cy);
    const MultiRingDetection rings = detectRings(images, ro);
    if (!rings.estimate)
      throw std::runtime_error("--checkerboard: the lens model is calibrated (" + cb.notes.back() +
                               ") but no ring was found about its centre in these images; give "
                               "--radius-inner and --radius-outer");
    // The used ring: the edges moved inwards by 1 px + 2 x the edge blur.
    lens.radius_inner = rings.estimate->radius_inner + 1.0 + 2.0 * rings.estimate->edge_width_inner;
    lens.radius_outer = rings.estimate->radius_outer - 1.0 - 2.0 * rings.estimate->edge_width_outer;
    char buf[160];
    std::snprintf(buf, sizeof buf, "ring %.1f..%.1f px: edges detected about the model's centre, "
                  "minus 1 px + 2 x edge blur", lens.radius_inner, lens.radius_outer);
    out.notes.push_back(buf);
  }
  finishModelCalibration(c, options, {}, "checkerboard calibration", out.notes);
  return out;
}

}  // namespace omnipose::calibrate
