#include "omnipose/calibrate/preview.hpp"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace omnipose::calibrate {
namespace {

constexpr double kPi = std::numbers::pi;
const cv::Scalar kGreen(60, 220, 60), kRed(40, 40, 235), kBlue(235, 120, 30),
    kYellow(0, 230, 255), kWhite(255, 255, 255), kMagenta(220, 60, 220);

cv::Mat toBgr8(const cv::Mat& image) {
  cv::Mat m = image;
  if (m.depth() != CV_8U) {
    cv::Mat tmp;
    m.convertTo(tmp, CV_8U);
    m = tmp;
  }
  cv::Mat out;
  if (m.channels() == 1) cv::cvtColor(m, out, cv::COLOR_GRAY2BGR);
  else if (m.channels() == 4) cv::cvtColor(m, out, cv::COLOR_BGRA2BGR);
  else out = m.clone();
  return out;
}

cv::Point2f pt(const Eigen::Vector2d& p) {
  return {static_cast<float>(p.x()), static_cast<float>(p.y())};
}

/// Draws with 4 bits of sub-pixel precision.
void circle(cv::Mat& img, const Eigen::Vector2d& c, double r, const cv::Scalar& colour, int t) {
  constexpr int kShift = 4;
  cv::circle(img, cv::Point(static_cast<int>(std::lround(c.x() * 16)),
                            static_cast<int>(std::lround(c.y() * 16))),
             static_cast<int>(std::lround(r * 16)), colour, t, cv::LINE_AA, kShift);
}

void label(cv::Mat& img, const std::string& text, cv::Point at, double scale,
           const cv::Scalar& colour) {
  cv::putText(img, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, cv::Scalar(0, 0, 0), 3, cv::LINE_AA);
  cv::putText(img, text, at, cv::FONT_HERSHEY_SIMPLEX, scale, colour, 1, cv::LINE_AA);
}

}  // namespace

cv::Mat unwrapColour(const cv::Mat& frame, const Calibration& cal) {
  const int w = cal.panorama.width, h = cal.panorama.height;
  cv::Mat map_x(h, w, CV_32FC1), map_y(h, w, CV_32FC1);
  for (int v = 0; v < h; ++v)
    for (int u = 0; u < w; ++u) {
      const Eigen::Vector2d p = cal.omniPixel(u, v);
      const bool seen = p.allFinite();  // else no bearing in the lens model: black
      map_x.at<float>(v, u) = seen ? static_cast<float>(p.x()) : -1.0f;
      map_y.at<float>(v, u) = seen ? static_cast<float>(p.y()) : -1.0f;
    }
  cv::Mat pano;
  cv::remap(toBgr8(frame), pano, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT);
  return pano;
}

namespace {

/// The first frame with the detected edges, the ring used, the centre and the axes drawn.
cv::Mat annotatedDonut(const cv::Mat& frame, const Calibration& cal, const RingDetection* detection) {
  const auto& lens = cal.omni;
  const Eigen::Vector2d c(lens.center_x, lens.center_y);
  cv::Mat donut = toBgr8(frame);
  const double thick = std::max(1.0, std::max(donut.cols, donut.rows) / 700.0);
  const int t = static_cast<int>(std::lround(thick));
  if (detection) {
    for (const RingEdge* e : {&detection->inner, &detection->outer}) {
      for (int i : e->inliers)
        cv::circle(donut, pt(e->points[static_cast<std::size_t>(i)]), t, kYellow, cv::FILLED);
      circle(donut, e->circle.center, e->circle.radius, kGreen, t);
    }
  }
  circle(donut, c, lens.radius_outer, kRed, t);
  circle(donut, c, lens.radius_inner, kBlue, t);
  const int cross = static_cast<int>(8 * thick);
  cv::line(donut, pt(c) - cv::Point2f(cross, 0), pt(c) + cv::Point2f(cross, 0), kMagenta, t);
  cv::line(donut, pt(c) - cv::Point2f(0, cross), pt(c) + cv::Point2f(0, cross), kMagenta, t);

  // Axes: +x at image angle a0, +y (theta = 90 deg) at a0 +- 90 deg by the direction.
  const double sign = lens.azimuth_direction == AzimuthDirection::kCw ? 1.0 : -1.0;
  const double a0 = lens.azimuth_zero_deg * kPi / 180.0;
  auto at = [&](double theta, double r) {
    const double a = a0 + sign * theta;
    return Eigen::Vector2d(c.x() + r * std::cos(a), c.y() + r * std::sin(a));
  };
  const double r_axis = lens.radius_outer * 1.08;
  cv::arrowedLine(donut, pt(at(0, lens.radius_inner * 0.3)), pt(at(0, r_axis)), kRed, t + 1,
                  cv::LINE_AA, 0, 0.04);
  cv::arrowedLine(donut, pt(at(kPi / 2, lens.radius_inner * 0.3)), pt(at(kPi / 2, r_axis)),
                  kGreen, t + 1, cv::LINE_AA, 0, 0.04);
  const double fs = 0.5 * thick;
  label(donut, "+x fwd", pt(at(0, r_axis + 12 * thick)), fs, kRed);
  label(donut, "+y left", pt(at(kPi / 2, r_axis + 12 * thick)), fs, kGreen);
  // Arc arrow: azimuth grows counter-clockwise seen from above, from +x toward +y.
  std::vector<cv::Point> arc;
  const double r_arc = 0.5 * (lens.radius_inner + lens.radius_outer) * 0.35 + 0.65 * lens.radius_inner;
  for (int k = 0; k <= 40; ++k) {
    const Eigen::Vector2d p = at(kPi / 2 * (0.15 + 0.6 * k / 40.0), r_arc);
    arc.emplace_back(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
  }
  cv::polylines(donut, arc, false, kYellow, t, cv::LINE_AA);
  cv::arrowedLine(donut, arc[arc.size() - 4], arc.back(), kYellow, t, cv::LINE_AA, 0, 1.0);

  return donut;
}

/// A frame unwrapped, with azimuth ticks every 45 deg and the horizon row.
cv::Mat annotatedPanorama(const cv::Mat& frame, const Calibration& cal) {
  cv::Mat p = unwrapColour(frame, cal);
  for (int deg = 0; deg < 360; deg += 45) {
    const int u = static_cast<int>(std::lround(cal.panorama.column(deg * kPi / 180.0)));
    cv::line(p, {u, 0}, {u, deg % 90 == 0 ? p.rows / 6 : p.rows / 12}, kYellow, 1);
    if (deg % 90 == 0) label(p, std::to_string(deg), {u + 3, 14}, 0.45, kYellow);
  }
  const int vh = static_cast<int>(std::lround(cal.panorama.horizon_row));
  for (int u = 0; u < p.cols; u += 12) cv::line(p, {u, vh}, {u + 5, vh}, kMagenta, 1);
  return p;
}

}  // namespace

cv::Mat renderPreview(std::span<const cv::Mat> frames, const Calibration& cal,
                      const RingDetection* detection, std::span<const std::string> lines,
                      int max_panoramas) {
  if (frames.empty()) throw std::invalid_argument("renderPreview: no frames");
  const cv::Mat donut = annotatedDonut(frames.front(), cal, detection);
  std::vector<cv::Mat> panos;
  const int n_pano = std::min<int>(max_panoramas, static_cast<int>(frames.size()));
  for (int k = 0; k < n_pano; ++k) panos.push_back(annotatedPanorama(frames[static_cast<std::size_t>(k)], cal));

  // --- composite ------------------------------------------------------------------------
  const int max_width = 1800;
  int width = donut.cols;
  for (const auto& p : panos) width = std::max(width, std::min(p.cols, max_width));
  const int line_h = 18;
  const int text_h = static_cast<int>(lines.size()) * line_h + 30;
  std::vector<cv::Mat> parts;
  parts.push_back(donut);
  for (auto& p : panos) {
    if (p.cols > max_width) {
      cv::Mat s;
      cv::resize(p, s, {}, static_cast<double>(max_width) / p.cols,
                 static_cast<double>(max_width) / p.cols, cv::INTER_AREA);
      p = s;
    }
    parts.push_back(p);
  }
  int height = text_h;
  for (const auto& p : parts) height += p.rows + 24;
  cv::Mat canvas(height, width, CV_8UC3, cv::Scalar(32, 32, 32));
  int y = 0;
  for (std::size_t k = 0; k < parts.size(); ++k) {
    const auto& p = parts[k];
    const int x = (width - p.cols) / 2;
    p.copyTo(canvas(cv::Rect(x, y, p.cols, p.rows)));
    y += p.rows;
    const std::string caption =
        k == 0 ? "donut: green = fitted edges (yellow = edge points), red/blue = used ring"
               : "panorama " + std::to_string(k - 1) +
                     ": theta grows to the right, so with the right azimuth_direction it is the "
                     "mirror image of a photo (text reads mirrored); 0 tick = +x; magenta = horizon";
    label(canvas, caption, {8, y + 17}, 0.5, kWhite);
    y += 24;
  }
  for (const auto& l : lines) {
    y += line_h;
    label(canvas, l, {8, y}, 0.45, kWhite);
  }
  return canvas;
}

}  // namespace omnipose::calibrate
