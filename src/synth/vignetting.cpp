#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "omnipose/synth/vignetting.hpp"

namespace omnipose::synth {

std::vector<std::string> Vignetting::validate() const {
  std::vector<std::string> p;
  if (!(strength >= 0 && strength <= 1)) p.push_back("vignetting strength: must be in [0, 1]");
  return p;
}

double Vignetting::factor(const Calibration& c, double x, double y) const {
  const double s = c.ringRadius(x, y) / c.omni.radius_outer;
  return std::max(0.0, 1.0 - strength * s * s);
}

cv::Mat Vignetting::factors(const Calibration& c, OutputKind output) const {
  if (output == OutputKind::kOmni) {
    cv::Mat f(c.omni.image_height, c.omni.image_width, CV_32FC1);
    for (int y = 0; y < f.rows; ++y) {
      float* row = f.ptr<float>(y);
      for (int x = 0; x < f.cols; ++x) row[x] = static_cast<float>(factor(c, x, y));
    }
    return f;
  }
  cv::Mat f(c.panorama.size(), CV_32FC1);
  for (int v = 0; v < f.rows; ++v) {
    float* row = f.ptr<float>(v);
    for (int u = 0; u < f.cols; ++u) {
      const Eigen::Vector2d p = c.omniPixel(u, v);
      row[u] = std::isfinite(p.x()) && std::isfinite(p.y())
                   ? static_cast<float>(factor(c, p.x(), p.y()))
                   : 1.0f;
    }
  }
  return f;
}

void Vignetting::apply(cv::Mat& image, const Calibration& c, OutputKind output) const {
  if (const auto problems = validate(); !problems.empty()) {
    throw std::invalid_argument("Vignetting::apply: " + problems.front());
  }
  const cv::Mat f = factors(c, output);
  if (image.type() != CV_32FC1 || image.size() != f.size()) {
    throw std::invalid_argument("Vignetting::apply: expected a CV_32FC1 image of the " +
                                std::string(toString(output)) + " size");
  }
  cv::multiply(image, f, image);
}

}  // namespace omnipose::synth
