#include <cmath>
#include <numbers>
#include <stdexcept>

#include "omnipose/synth/occluder.hpp"

namespace omnipose::synth {
namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

/// Angle of image point (x, y) from the sector centre, wrapped to (-180, 180] degrees.
double offsetDeg(const Calibration& c, const Occluder& o, double x, double y) {
  const double a = std::atan2(y - c.omni.center_y, x - c.omni.center_x) / kDeg;
  return std::remainder(a - o.image_angle_deg, 360.0);
}

/// A fixed texture: a pole with a few cables and bolts, hashed noise for grain.
float pattern(const Calibration& c, double x, double y, double offset_deg, double half_width) {
  const double r = std::hypot(x - c.omni.center_x, y - c.omni.center_y);
  const double across = offset_deg / half_width;  // -1 .. 1 across the sector
  double v = 70.0 + 50.0 * std::cos(across * 1.4);                        // shaded pole
  v += 35.0 * std::sin(r * 0.21) * std::exp(-4.0 * across * across);       // bolts along it
  v += 25.0 * (std::fmod(std::floor(across * 6.0 + 6.0), 2.0) - 0.5);      // cable bands
  const std::uint32_t h = static_cast<std::uint32_t>(x) * 73856093u ^
                          static_cast<std::uint32_t>(y) * 19349663u;
  v += static_cast<double>((h * 2654435761u) >> 24) / 255.0 * 16.0 - 8.0;  // grain
  return static_cast<float>(std::clamp(v, 0.0, 255.0));
}

}  // namespace

std::vector<std::string> Occluder::validate() const {
  std::vector<std::string> p;
  if (!std::isfinite(image_angle_deg)) p.push_back("occluder angle: must be finite");
  if (!(width_deg > 0 && width_deg < 360)) p.push_back("occluder width: must be in (0, 360) degrees");
  return p;
}

void Occluder::paint(cv::Mat& image, const Calibration& c) const {
  if (image.type() != CV_32FC1) throw std::invalid_argument("Occluder::paint: expected CV_32FC1");
  const double half = 0.5 * width_deg;
  for (int y = 0; y < image.rows; ++y) {
    float* row = image.ptr<float>(y);
    for (int x = 0; x < image.cols; ++x) {
      const double r = c.ringRadius(x, y);
      if (r < c.omni.radius_inner - 2 || r > c.omni.radius_outer + 2) continue;
      const double off = offsetDeg(c, *this, x, y);
      if (std::abs(off) <= half) row[x] = pattern(c, x, y, off, half);
    }
  }
}

cv::Mat Occluder::mask(const Calibration& c, double margin_deg) const {
  cv::Mat m(c.omni.image_height, c.omni.image_width, CV_8UC1, cv::Scalar(255));
  const double half = 0.5 * width_deg + margin_deg;
  for (int y = 0; y < m.rows; ++y)
    for (int x = 0; x < m.cols; ++x)
      if (std::abs(offsetDeg(c, *this, x, y)) <= half) m.at<uchar>(y, x) = 0;
  return m;
}

Occluder parseOccluder(const std::string& text) {
  const auto comma = text.find(',');
  try {
    if (comma == std::string::npos) throw std::invalid_argument(text);
    std::size_t end1 = 0, end2 = 0;
    Occluder o{std::stod(text.substr(0, comma), &end1), std::stod(text.substr(comma + 1), &end2)};
    if (end1 != comma || end2 != text.size() - comma - 1) throw std::invalid_argument(text);
    if (const auto p = o.validate(); !p.empty()) throw std::invalid_argument(p.front());
    return o;
  } catch (const std::invalid_argument& e) {
    throw std::invalid_argument("'" + text + "' is not ANGLE,WIDTH in degrees (" + e.what() + ")");
  } catch (const std::out_of_range&) {
    throw std::invalid_argument("'" + text + "' is out of range");
  }
}

}  // namespace omnipose::synth
