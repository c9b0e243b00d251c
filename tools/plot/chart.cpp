#include "chart.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <opencv2/imgproc.hpp>
#include <utility>

namespace omnipose::plot {
namespace {

constexpr int kFont = cv::FONT_HERSHEY_SIMPLEX;
constexpr double kFontScale = 0.5;
constexpr int kShift = 4;  // sub-pixel drawing: coordinates in 1/16 pixel
constexpr double kSub = 1 << kShift;
const cv::Scalar kBlack(0, 0, 0), kWhite(255, 255, 255), kGrid(225, 225, 225),
    kAxis(90, 90, 90);

cv::Point sub(double x, double y) {
  return {static_cast<int>(std::lround(x * kSub)), static_cast<int>(std::lround(y * kSub))};
}

/// 1, 2 or 5 times a power of ten, so that `range` gives about `target` ticks.
double niceStep(double range, int target) {
  const double raw = range / target;
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double n = raw / mag;
  return (n < 1.5 ? 1.0 : n < 3.0 ? 2.0 : n < 7.0 ? 5.0 : 10.0) * mag;
}

/// Tick positions (axis units) and their labels.
using Ticks = std::vector<std::pair<double, std::string>>;

/// Ticks of a logarithmic axis over [lo, hi] (log10 units): log10 of 1, 2 and 5 times
/// each power of ten inside, with their labels.
Ticks logTicks(double lo, double hi) {
  Ticks ticks;
  for (int d = static_cast<int>(std::floor(lo)); d <= static_cast<int>(std::ceil(hi)); ++d) {
    for (int m : {1, 2, 5}) {
      const double t = d + std::log10(static_cast<double>(m));
      if (t < lo - 1e-9 || t > hi + 1e-9) continue;
      char buf[32];
      std::snprintf(buf, sizeof(buf), "%g", m * std::pow(10.0, d));
      ticks.emplace_back(t, buf);
    }
  }
  return ticks;
}

std::string tickLabel(double value, double step) {
  const int decimals = std::max(0, static_cast<int>(-std::floor(std::log10(step) + 1e-9)));
  char buf[32];
  std::snprintf(buf, sizeof(buf), "%.*f", decimals, std::abs(value) < step * 1e-6 ? 0.0 : value);
  return buf;
}

/// Ticks of an axis over [lo, hi] (axis units): logTicks on a logarithmic axis, else about
/// `target` ticks at a nice step.
Ticks axisTicks(double lo, double hi, bool log, int target) {
  if (log) return logTicks(lo, hi);
  Ticks ticks;
  const double step = niceStep(hi - lo, target);
  for (double t = std::ceil(lo / step) * step; t <= hi + 1e-9 * step; t += step)
    ticks.emplace_back(t, tickLabel(t, step));
  return ticks;
}

/// A data value in axis units: log10 of it on a logarithmic axis (NaN, not drawn, if <= 0).
double axisValue(double v, bool log) {
  if (!log) return v;
  return v > 0.0 ? std::log10(v) : std::numeric_limits<double>::quiet_NaN();
}

void text(cv::Mat& img, const std::string& s, cv::Point at, double scale = kFontScale,
          const cv::Scalar& color = kBlack, int thickness = 1) {
  cv::putText(img, s, at, kFont, scale, color, thickness, cv::LINE_AA);
}

cv::Size textSize(const std::string& s, double scale = kFontScale, int thickness = 1) {
  int baseline = 0;
  return cv::getTextSize(s, kFont, scale, thickness, &baseline);
}

void dashedLine(cv::Mat& img, cv::Point2d a, cv::Point2d b, const cv::Scalar& color, int thickness,
                double& phase) {
  constexpr double kOn = 9.0, kOff = 6.0;
  const double length = std::hypot(b.x - a.x, b.y - a.y);
  if (length <= 0) return;
  const cv::Point2d dir = (b - a) / length;
  double s = 0.0;
  while (s < length) {
    const double in_period = std::fmod(phase, kOn + kOff);
    const double left = in_period < kOn ? kOn - in_period : kOn + kOff - in_period;
    const double e = std::min(length, s + left);
    if (in_period < kOn) {
      const cv::Point2d p = a + dir * s, q = a + dir * e;
      cv::line(img, sub(p.x, p.y), sub(q.x, q.y), color, thickness, cv::LINE_AA, kShift);
    }
    phase += e - s;
    s = e;
  }
}

/// Data coordinates (log10 of the value on a logarithmic axis) to plot-area pixels.
struct AxisMap {
  cv::Rect area;
  double xlo, xhi, ylo, yhi;
  bool log_x, log_y;
  double tx(double x) const { return axisValue(x, log_x); }
  double ty(double y) const { return axisValue(y, log_y); }
  /// The image pixel of an axis value, relative to the plot area's corner.
  cv::Point2d point(double x, double y) const {
    const double px = area.x + (x - xlo) / (xhi - xlo) * area.width;
    const double py = area.y + (yhi - y) / (yhi - ylo) * area.height;
    return {px - area.x, py - area.y};
  }
};

/// One series into `view` (the plot area), points and lines as its style says.
void drawSeries(cv::Mat& view, const Series& s, const AxisMap& map) {
  const std::size_t n = std::min(s.x.size(), s.y.size());
  const bool lines = s.style == Style::kLine || s.style == Style::kDashed ||
                     s.style == Style::kLineMarkers;
  const bool markers = s.style == Style::kMarkers || s.style == Style::kLineMarkers ||
                       s.style == Style::kHollowMarkers;
  double phase = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const double x = map.tx(s.x[i]), y = map.ty(s.y[i]);
    if (!std::isfinite(y) || !std::isfinite(x)) continue;
    const cv::Point2d p = map.point(x, y);
    const double x1 = i + 1 < n ? map.tx(s.x[i + 1]) : x, y1 = i + 1 < n ? map.ty(s.y[i + 1]) : y;
    if (lines && i + 1 < n && std::isfinite(y1) && std::isfinite(x1)) {
      const cv::Point2d q = map.point(x1, y1);
      if (s.style == Style::kDashed) dashedLine(view, p, q, s.color, s.thickness, phase);
      else
        cv::line(view, sub(p.x, p.y), sub(q.x, q.y), s.color, s.thickness, cv::LINE_AA, kShift);
    }
    if (markers) {
      const bool hollow = s.style == Style::kHollowMarkers;
      cv::circle(view, sub(p.x, p.y), static_cast<int>(3.5 * kSub), s.color,
                 hollow ? 1 : cv::FILLED, cv::LINE_AA, kShift);
    }
  }
}

/// `label` turned a quarter left, left of `area`, centred on it vertically.
void drawVerticalLabel(cv::Mat& img, const std::string& label_text, const cv::Rect& area) {
  const cv::Size ts = textSize(label_text);
  cv::Mat label(ts.height + 8, ts.width + 4, CV_8UC3, kWhite);
  text(label, label_text, {2, ts.height + 2});
  cv::Mat rotated;
  cv::rotate(label, rotated, cv::ROTATE_90_COUNTERCLOCKWISE);
  const int x = 4, y = area.y + (area.height - rotated.rows) / 2;
  if (y >= 0 && y + rotated.rows <= img.rows && x + rotated.cols <= img.cols)
    rotated.copyTo(img(cv::Rect(x, y, rotated.cols, rotated.rows)));
}

/// The legend of the labelled series, in the column right of `area`.
void drawLegend(cv::Mat& img, const std::vector<Series>& series, const cv::Rect& area) {
  std::vector<const Series*> entries;
  int width = 0;
  for (const Series& s : series) {
    if (s.label.empty()) continue;
    entries.push_back(&s);
    width = std::max(width, textSize(s.label).width);
  }
  if (entries.empty()) return;
  const int row = 19;
  const cv::Rect box(area.x + area.width + 10, area.y, width + 46,
                     row * static_cast<int>(entries.size()) + 8);
  cv::rectangle(img, box, {200, 200, 200}, 1);
  for (std::size_t k = 0; k < entries.size(); ++k) {
    const Series& s = *entries[k];
    const int y = box.y + 4 + row * static_cast<int>(k) + row / 2;
    const cv::Point2d a(box.x + 6, y), b(box.x + 32, y);
    double phase = 0.0;
    if (s.style == Style::kDashed) dashedLine(img, a, b, s.color, s.thickness, phase);
    else if (s.style != Style::kMarkers && s.style != Style::kHollowMarkers)
      cv::line(img, sub(a.x, a.y), sub(b.x, b.y), s.color, s.thickness, cv::LINE_AA, kShift);
    if (s.style == Style::kMarkers || s.style == Style::kLineMarkers ||
        s.style == Style::kHollowMarkers)
      cv::circle(img, {box.x + 19, y}, 4, s.color,
                 s.style == Style::kHollowMarkers ? 1 : cv::FILLED, cv::LINE_AA);
    text(img, s.label, {box.x + 38, y + 5});
  }
}

}  // namespace

cv::Scalar paletteColor(int i) {
  static const cv::Scalar kPalette[] = {
      {180, 119, 31}, {14, 127, 255}, {44, 160, 44},  {40, 39, 214},   {189, 103, 148},
      {75, 86, 140},  {194, 119, 227}, {127, 127, 127}, {34, 189, 188}, {207, 190, 23}};
  return kPalette[((i % 10) + 10) % 10];
}

Chart::Chart(std::string title, std::string x_label, std::string y_label)
    : title_(std::move(title)), x_label_(std::move(x_label)), y_label_(std::move(y_label)) {}

void Chart::add(Series series) { series_.push_back(std::move(series)); }

void Chart::setXRange(double lo, double hi) {
  fixed_x_ = true;
  x_lo_ = lo;
  x_hi_ = hi;
}

void Chart::setYRange(double lo, double hi) {
  fixed_y_ = true;
  y_lo_ = lo;
  y_hi_ = hi;
}

void Chart::setLogScale(bool x, bool y) {
  log_x_ = x;
  log_y_ = y;
}

void Chart::setMinRightMargin(int pixels) { min_right_margin_ = pixels; }

int Chart::rightMargin() const {
  int width = 0;
  for (const Series& s : series_)
    if (!s.label.empty()) width = std::max(width, textSize(s.label).width + 62);
  return std::max(min_right_margin_, width);
}

cv::Mat Chart::render(cv::Size size) const {
  cv::Mat img(size, CV_8UC3, kWhite);

  // Data ranges, in axis units (log10 of the value on a logarithmic axis).
  auto tx = [&](double x) { return axisValue(x, log_x_); };
  auto ty = [&](double y) { return axisValue(y, log_y_); };
  double xlo = tx(x_lo_), xhi = tx(x_hi_), ylo = ty(y_lo_), yhi = ty(y_hi_);
  if (!fixed_x_ || !fixed_y_) {
    double ax = std::numeric_limits<double>::infinity(), bx = -ax, ay = ax, by = -ax;
    for (const Series& s : series_) {
      for (std::size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
        const double x = tx(s.x[i]), y = ty(s.y[i]);
        if (!std::isfinite(x) || !std::isfinite(y)) continue;
        ax = std::min(ax, x);
        bx = std::max(bx, x);
        ay = std::min(ay, y);
        by = std::max(by, y);
      }
    }
    if (!std::isfinite(ax)) ax = 0, bx = 1, ay = 0, by = 1;
    if (!fixed_x_) xlo = ax, xhi = bx;
    if (!fixed_y_) {
      const double pad = 0.05 * std::max(by - ay, 1e-9);
      ylo = ay - pad;
      yhi = by + pad;
    }
  }
  if (!std::isfinite(xlo) || !std::isfinite(xhi)) xlo = 0, xhi = 1;
  if (!std::isfinite(ylo) || !std::isfinite(yhi)) ylo = 0, yhi = 1;
  if (xhi - xlo < 1e-12) xlo -= 0.5, xhi += 0.5;
  if (yhi - ylo < 1e-12) ylo -= 0.5, yhi += 0.5;

  // Plot area.
  const int left = kLeftMargin, right = rightMargin(), top = 34, bottom = 50;
  const cv::Rect area(left, top, size.width - left - right, size.height - top - bottom);
  auto px = [&](double x) { return area.x + (x - xlo) / (xhi - xlo) * area.width; };
  auto py = [&](double y) { return area.y + (yhi - y) / (yhi - ylo) * area.height; };

  // Grid, ticks and tick labels.
  for (const auto& [x, label] : axisTicks(xlo, xhi, log_x_, std::max(2, area.width / 90))) {
    const int X = static_cast<int>(std::lround(px(x)));
    cv::line(img, {X, area.y}, {X, area.y + area.height}, kGrid, 1);
    text(img, label, {X - textSize(label).width / 2, area.y + area.height + 18});
  }
  for (const auto& [y, label] : axisTicks(ylo, yhi, log_y_, std::max(2, area.height / 45))) {
    const int Y = static_cast<int>(std::lround(py(y)));
    cv::line(img, {area.x, Y}, {area.x + area.width, Y}, kGrid, 1);
    text(img, label, {area.x - 6 - textSize(label).width, Y + 5});
  }
  if (!log_y_ && ylo < 0 && yhi > 0) {
    const int Y = static_cast<int>(std::lround(py(0)));
    cv::line(img, {area.x, Y}, {area.x + area.width, Y}, {170, 170, 170}, 1);
  }

  // Series, clipped to the plot area by drawing into its view.
  const AxisMap map{area, xlo, xhi, ylo, yhi, log_x_, log_y_};
  cv::Mat view = img(area);
  for (const Series& s : series_) drawSeries(view, s, map);

  // Frame, title, axis labels.
  cv::rectangle(img, area, kAxis, 1);
  text(img, title_, {area.x + (area.width - textSize(title_, 0.6, 1).width) / 2, 22}, 0.6, kBlack,
       1);
  text(img, x_label_,
       {area.x + (area.width - textSize(x_label_).width) / 2, size.height - 10});
  drawVerticalLabel(img, y_label_, area);

  drawLegend(img, series_, area);
  return img;
}

cv::Mat stackVertical(const std::vector<cv::Mat>& images) {
  int width = 0, height = 0;
  for (const cv::Mat& m : images) {
    width = std::max(width, m.cols);
    height += m.rows;
  }
  cv::Mat out(std::max(height, 1), std::max(width, 1), CV_8UC3, kWhite);
  int y = 0;
  for (const cv::Mat& m : images) {
    m.copyTo(out(cv::Rect((width - m.cols) / 2, y, m.cols, m.rows)));
    y += m.rows;
  }
  return out;
}

cv::Mat captioned(const cv::Mat& grey, int width, const std::string& caption, int left,
                  int right) {
  cv::Mat g8, bgr, scaled;
  grey.convertTo(g8, CV_8U);
  cv::cvtColor(g8, bgr, cv::COLOR_GRAY2BGR);
  const int margin = left;
  const int w = std::max(1, width - left - right);
  cv::resize(bgr, scaled, {w, std::max(1, grey.rows * w / grey.cols)}, 0, 0, cv::INTER_AREA);
  const int caption_h = 24;
  cv::Mat out(scaled.rows + caption_h + 6, width, CV_8UC3, kWhite);
  text(out, caption, {margin, 17});
  scaled.copyTo(out(cv::Rect(margin, caption_h, scaled.cols, scaled.rows)));
  return out;
}

}  // namespace omnipose::plot
