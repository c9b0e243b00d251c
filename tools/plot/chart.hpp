#pragma once
// A small line/scatter chart drawn with OpenCV (axes, ticks, grid, legend), so the
// evaluation figures need nothing beyond the project's own dependencies.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace omnipose::plot {

/// How a series is drawn. NaN y values break lines (a missing estimate is a gap).
enum class Style { kLine, kDashed, kMarkers, kLineMarkers, kHollowMarkers };

struct Series {
  std::vector<double> x, y;
  cv::Scalar color;  ///< BGR
  std::string label;  ///< empty: not in the legend
  Style style = Style::kLine;
  int thickness = 2;  ///< pixels
};

/// Colour i of a fixed qualitative palette (Tableau 10), BGR.
cv::Scalar paletteColor(int i);

class Chart {
 public:
  /// Pixels left of the plot area (tick labels and the y label).
  static constexpr int kLeftMargin = 78;

  Chart(std::string title, std::string x_label, std::string y_label);

  void add(Series series);
  /// Fixes the x range (default: the data's).
  void setXRange(double lo, double hi);
  /// Fixes the y range (default: the data's, padded by 5 %).
  void setYRange(double lo, double hi);
  /// Logarithmic x and/or y axis (ticks at 1, 2 and 5 times the powers of ten); points
  /// with a value <= 0 on a logarithmic axis are not drawn. Ranges stay in data units.
  void setLogScale(bool x, bool y);

  /// Keeps at least this many pixels right of the plot area (to align stacked charts).
  void setMinRightMargin(int pixels);
  /// Pixels right of the plot area: the legend column (labelled series) or a small margin.
  int rightMargin() const;

  /// Draws the chart into a new BGR image of `size` pixels.
  cv::Mat render(cv::Size size) const;

 private:
  std::string title_, x_label_, y_label_;
  std::vector<Series> series_;
  int min_right_margin_ = 16;
  bool fixed_x_ = false, fixed_y_ = false;
  bool log_x_ = false, log_y_ = false;
  double x_lo_ = 0, x_hi_ = 1, y_lo_ = 0, y_hi_ = 1;
};

/// Stacks images (BGR) top to bottom, centred on a white canvas as wide as the widest.
cv::Mat stackVertical(const std::vector<cv::Mat>& images);
/// A grey image (any depth, 0..255) as a BGR image of `width` pixels with a caption above,
/// scaled to fit between `left` and `right` margins (e.g. a chart's plot area).
cv::Mat captioned(const cv::Mat& grey, int width, const std::string& caption, int left = 16,
                  int right = 16);

}  // namespace omnipose::plot
