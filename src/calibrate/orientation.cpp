#include "omnipose/calibrate/orientation.hpp"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <numbers>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

#include "common/format.hpp"
#include "common/named_values.hpp"
#include "omnipose/calibrate/ring_detector.hpp"
#include "omnipose/unwrapper.hpp"

namespace omnipose::calibrate {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr double kBandFraction = 0.25;  ///< inner / outer band of the ring for the up cue

using omnipose::detail::format;

}  // namespace

std::optional<ColumnShift> columnShift(const cv::Mat& previous, const cv::Mat& current) {
  if (previous.empty() || previous.size() != current.size() || previous.cols < 8) return {};
  cv::Mat p, c;
  previous.convertTo(p, CV_32F);
  current.convertTo(c, CV_32F);
  if (p.channels() != 1 || c.channels() != 1) return {};
  // Zero-mean rows, so the DC term does not dominate.
  for (int r = 0; r < p.rows; ++r) {
    p.row(r) -= cv::mean(p.row(r))[0];
    c.row(r) -= cv::mean(c.row(r))[0];
  }
  // Row-wise DFT; S(f) = sum_rows P_r(f) conj(C_r(f)) is the spectrum of
  // sum_x prev(x) cur(x - s), which peaks at s = du because prev(x) = cur(x - du).
  cv::Mat fp, fc;
  cv::dft(p, fp, cv::DFT_ROWS | cv::DFT_COMPLEX_OUTPUT);
  cv::dft(c, fc, cv::DFT_ROWS | cv::DFT_COMPLEX_OUTPUT);
  const int w = p.cols;
  cv::Mat s = cv::Mat::zeros(1, w, CV_32FC2);
  for (int r = 0; r < p.rows; ++r) {
    const auto* a = fp.ptr<cv::Vec2f>(r);
    const auto* b = fc.ptr<cv::Vec2f>(r);
    auto* o = s.ptr<cv::Vec2f>(0);
    for (int f = 0; f < w; ++f) {
      o[f][0] += a[f][0] * b[f][0] + a[f][1] * b[f][1];
      o[f][1] += a[f][1] * b[f][0] - a[f][0] * b[f][1];
    }
  }
  // Phase correlation: whiten the summed cross-power spectrum.
  auto* o = s.ptr<cv::Vec2f>(0);
  for (int f = 0; f < w; ++f) {
    const float m = std::hypot(o[f][0], o[f][1]);
    o[f] = m > 1e-12f ? o[f] / m : cv::Vec2f(0, 0);
  }
  cv::Mat corr;
  cv::dft(s, corr, cv::DFT_INVERSE | cv::DFT_REAL_OUTPUT | cv::DFT_SCALE);
  const auto* q = corr.ptr<float>(0);
  int best = 0;
  for (int k = 1; k < w; ++k)
    if (q[k] > q[best]) best = k;
  const double ym = q[(best - 1 + w) % w], y0 = q[best], yp = q[(best + 1) % w];
  const double den = ym - 2.0 * y0 + yp;
  const double delta = den < 0 ? std::clamp(0.5 * (ym - yp) / den, -0.5, 0.5) : 0.0;
  double second = 0.0;
  for (int k = 0; k < w; ++k) {
    const int d = std::min((k - best + w) % w, (best - k + w) % w);
    if (d > 3) second = std::max(second, static_cast<double>(q[k]));
  }
  ColumnShift out;
  out.du = best + delta;
  if (out.du > 0.5 * w) out.du -= w;
  out.peak = y0;
  out.peak_ratio = second > 0 ? y0 / second : std::numeric_limits<double>::infinity();
  return out;
}

DirectionResult directionFromTurnLeft(std::span<const cv::Mat> frames,
                                      const Calibration& calibration, double min_total_px) {
  if (frames.size() < 2)
    throw std::invalid_argument("turn-left sequence: needs at least 2 frames");
  Calibration cw = calibration;
  cw.omni.azimuth_direction = AzimuthDirection::kCw;
  Unwrapper unwrapper(cw, {});
  DirectionResult res;
  cv::Mat prev = unwrapper.makePanorama(), cur = unwrapper.makePanorama();
  for (std::size_t k = 0; k < frames.size(); ++k) {
    if (const auto ok = unwrapper.unwrap(frames[k], cur); !ok)
      throw std::invalid_argument(format("turn-left sequence: frame %zu: %s", k, ok.error().c_str()));
    if (k > 0) {
      const auto shift = columnShift(prev, cur);
      if (!shift) throw std::invalid_argument("turn-left sequence: panoramas do not correlate");
      res.shifts.push_back(*shift);
      res.total_du_cw += shift->du;
    }
    std::swap(prev, cur);
  }
  const double gamma_deg = 360.0 / calibration.panorama.width;
  res.direction = res.total_du_cw >= 0 ? AzimuthDirection::kCw : AzimuthDirection::kCcw;
  res.total_yaw_deg = std::abs(res.total_du_cw) * gamma_deg;
  int moved = 0, agree = 0;
  for (const auto& s : res.shifts) {
    if (std::abs(s.du) < 0.5) continue;
    ++moved;
    if ((s.du > 0) == (res.total_du_cw > 0)) ++agree;
  }
  res.decisive = std::abs(res.total_du_cw) >= min_total_px && moved > 0 && 3 * agree >= 2 * moved;
  std::string pairs;
  for (const auto& s : res.shifts) pairs += format("%s%+.1f", pairs.empty() ? "" : ", ", s.du);
  res.how = format(
      "turn-left sequence of %zu frames unwrapped with cw: du = [%s] px (sum %+.1f px); "
      "a left turn needs du > 0, so %s (turn %.1f deg)%s",
      frames.size(), pairs.c_str(), res.total_du_cw,
      res.direction == AzimuthDirection::kCw ? "cw" : "ccw (cw mirrors the panorama)",
      res.total_yaw_deg,
      res.decisive ? "" : "; NOT decisive (too little or inconsistent motion)");
  return res;
}

namespace {

constexpr detail::Named<UpCue> kUpCues[] = {
    {UpCue::kBright, "bright"}, {UpCue::kDark, "dark"}, {UpCue::kNone, "none"}};

}  // namespace

UpCue parseUpCue(const std::string& name) {
  if (const auto cue = detail::valueNamed(kUpCues, name)) return *cue;
  throw std::invalid_argument("up cue '" + name + "' is not " + detail::nameList(kUpCues));
}

const char* toString(UpCue cue) { return detail::nameOf(kUpCues, cue); }

OuterEdgeResult outerEdgeFromAppearance(std::span<const cv::Mat> frames, const OmniLens& lens,
                                        UpCue cue, OuterEdge fallback, double min_contrast) {
  OuterEdgeResult res;
  res.edge = fallback;
  const char* fallback_name = toString(fallback);
  if (cue == UpCue::kNone || frames.empty()) {
    res.how = format("no vertical cue (--up-cue none): default %s", fallback_name);
    return res;
  }
  // Samples of the inner and outer quarters of the ring on equally spaced rays (each ray
  // weighs the same); the statistic is the mean of the brightest quarter of each band
  // (lights, windows and sky are the brightest things and they are up).
  const int rays = 720, samples = 16;
  const double span = lens.radius_outer - lens.radius_inner;
  std::vector<float> inner, outer;
  for (const auto& frame : frames) {
    const cv::Mat grey = toGreyFloat(frame);
    cv::Mat map_x(rays, 2 * samples, CV_32FC1), map_y(rays, 2 * samples, CV_32FC1);
    for (int i = 0; i < rays; ++i) {
      const double a = 2.0 * kPi * i / rays;
      for (int j = 0; j < 2 * samples; ++j) {
        const bool is_outer = j >= samples;
        const double f = ((j % samples) + 0.5) / samples * kBandFraction;
        const double r = is_outer ? lens.radius_outer - f * span : lens.radius_inner + f * span;
        map_x.at<float>(i, j) = static_cast<float>(lens.center_x + r * std::cos(a));
        map_y.at<float>(i, j) = static_cast<float>(lens.center_y + r * std::sin(a));
      }
    }
    cv::Mat polar;
    cv::remap(grey, polar, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(-1));
    for (int i = 0; i < rays; ++i)
      for (int j = 0; j < 2 * samples; ++j) {
        const float v = polar.at<float>(i, j);
        if (v < 0) continue;  // outside the image
        (j >= samples ? outer : inner).push_back(v);
      }
  }
  if (inner.size() < 100 || outer.size() < 100) {
    res.how = format("ring not inside the image: default %s", fallback_name);
    return res;
  }
  auto brightQuarter = [](std::vector<float>& v) {
    std::sort(v.begin(), v.end());
    const std::size_t from = v.size() * 3 / 4;
    double s = 0.0;
    for (std::size_t i = from; i < v.size(); ++i) s += v[i];
    return s / static_cast<double>(v.size() - from);
  };
  res.inner_level = brightQuarter(inner);
  res.outer_level = brightQuarter(outer);
  res.contrast = (res.outer_level - res.inner_level) / std::max(1e-9, res.outer_level + res.inner_level);
  const bool outer_brighter = res.contrast > 0;
  const bool outer_is_up = cue == UpCue::kBright ? outer_brighter : !outer_brighter;
  const std::string levels =
      format("brightest-quarter mean grey: inner quarter of the ring %.1f, outer quarter %.1f "
             "(contrast %+.3f)", res.inner_level,
             res.outer_level, res.contrast);
  if (std::abs(res.contrast) < min_contrast) {
    res.how = format("up cue '%s' not decisive: %s, |contrast| < %.2f: default %s", toString(cue),
                     levels.c_str(), min_contrast, fallback_name);
    return res;
  }
  res.decisive = true;
  res.edge = outer_is_up ? OuterEdge::kTop : OuterEdge::kBottom;
  res.how = format("up cue '%s': %s; the %s side is up, so the outer ring is the %s edge",
                   toString(cue), levels.c_str(), outer_is_up ? "outer" : "inner",
                   toString(res.edge));
  return res;
}

double imageAngleDeg(const OmniLens& lens, const Eigen::Vector2d& point) {
  double a = std::atan2(point.y() - lens.center_y, point.x() - lens.center_x) * 180.0 / kPi;
  if (a < 0) a += 360.0;
  return a;
}

AzimuthDirection assumedDirection(OuterEdge outer_edge) {
  return outer_edge == OuterEdge::kTop ? AzimuthDirection::kCw : AzimuthDirection::kCcw;
}

}  // namespace omnipose::calibrate
