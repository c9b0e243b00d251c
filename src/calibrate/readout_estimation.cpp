#include "omnipose/calibrate/readout_estimation.hpp"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <optional>
#include <stdexcept>

#include "common/format.hpp"
#include "common/problem_list.hpp"

namespace omnipose::calibrate {
namespace {

constexpr int kMinFrames = 10;
constexpr int kMinPairs = 8;

std::string fixed(double v, int digits = 4) { return detail::fixed(v, digits); }

/// Mean turn per pair below which the frames cannot show the readout, radians (0.1 deg).
constexpr double kMinMeanTurnRad = 0.1 * std::numbers::pi / 180.0;

/// Mean squared horizontal tau over the tracked pairs of `frames` replayed with `readout`;
/// nullopt with fewer than kMinPairs tracked pairs. `mean_turn`: the mean rotation angle
/// per tracked pair, radians.
std::optional<double> translationScore(Calibration calibration, double readout,
                                       std::span<const cv::Mat> frames,
                                       std::span<const double> times,
                                       const OdometryOptions& options, int& pairs,
                                       double& mean_turn) {
  calibration.sensor.readout_s = readout;
  Odometry odometry(calibration, options);
  double sum = 0.0, turn = 0.0;
  pairs = 0;
  for (std::size_t k = 0; k < frames.size(); ++k) {
    const auto r = odometry.process(frames[k], {times[k]});
    if (!r || r->state != TrackState::kTracked) continue;
    sum += r->relative.estimate.tau.head<2>().squaredNorm();
    turn += r->relative.estimate.omega.norm();
    ++pairs;
  }
  mean_turn = pairs > 0 ? turn / pairs : 0.0;
  if (pairs < kMinPairs) return std::nullopt;
  return sum / pairs;
}

}  // namespace

std::vector<std::string> ReadoutSearchOptions::validate() const {
  std::vector<std::string> p;
  if (!(max_s > 0.0 && max_s <= SensorTiming::kMaxReadoutS))
    p.push_back("max_s: must be in (0, " + fixed(SensorTiming::kMaxReadoutS, 1) + "] s");
  if (!(coarse_step_s > 0.0 && coarse_step_s <= max_s))
    p.push_back("coarse_step_s: must be in (0, max_s]");
  if (!(fine_step_s > 0.0 && fine_step_s <= coarse_step_s))
    p.push_back("fine_step_s: must be in (0, coarse_step_s]");
  if (!(min_contrast >= 0.0 && std::isfinite(min_contrast)))
    p.push_back("min_contrast: must be a finite number >= 0");
  for (const auto& q : odometry.validate()) p.push_back("odometry." + q);
  return p;
}

ReadoutEstimate estimateReadout(const Calibration& calibration, std::span<const cv::Mat> frames,
                                std::span<const double> times_s,
                                const ReadoutSearchOptions& options) {
  detail::throwIfProblems("estimateReadout: invalid options", options.validate());
  if (frames.size() != times_s.size())
    throw std::invalid_argument("estimateReadout: " + std::to_string(frames.size()) +
                                " frames but " + std::to_string(times_s.size()) + " times");
  ReadoutEstimate out;
  if (static_cast<int>(frames.size()) < kMinFrames) {
    out.summary = "cannot: " + std::to_string(frames.size()) + " frames, at least " +
                  std::to_string(kMinFrames) + " needed";
    return out;
  }

  int pairs = 0, fewest_pairs = std::numeric_limits<int>::max();
  double mean_turn = 0.0;
  const auto score = [&](double r) -> std::optional<double> {
    for (const auto& [tried, s] : out.curve)
      if (std::abs(tried - r) < 1e-9) return s;
    const auto s =
        translationScore(calibration, r, frames, times_s, options.odometry, pairs, mean_turn);
    fewest_pairs = std::min(fewest_pairs, pairs);
    if (s) out.curve.emplace_back(r, *s);
    return s;
  };
  const auto best = [&] {
    return *std::min_element(out.curve.begin(), out.curve.end(),
                             [](const auto& a, const auto& b) { return a.second < b.second; });
  };

  const int half = static_cast<int>(std::floor(options.max_s / options.coarse_step_s + 1e-9));
  for (int i = -half; i <= half; ++i) {
    if (!score(i * options.coarse_step_s)) {
      out.summary = "cannot: only " + std::to_string(pairs) + " frame pairs tracked at readout " +
                    fixed(i * options.coarse_step_s) + " s (at least " +
                    std::to_string(kMinPairs) + " needed)";
      return out;
    }
    if (i == -half && mean_turn < kMinMeanTurnRad) {
      out.summary = "cannot: the camera hardly turns (" +
                    fixed(mean_turn * 180.0 / std::numbers::pi, 3) +
                    " deg per frame pair on average over " + std::to_string(pairs) +
                    " pairs): record it turning in place, speeding up and slowing down";
      return out;
    }
  }
  // A flat curve says nothing, wherever its minimum happens to be (not the edge message).
  const auto [coarse_best, coarse_score] = best();
  double highest = coarse_score;
  for (const auto& [r, s] : out.curve) highest = std::max(highest, s);
  const double spread =
      (highest - coarse_score) / std::max(coarse_score, std::numeric_limits<double>::min());
  if (!(spread >= options.min_contrast)) {
    out.summary = "cannot: the frames hardly depend on the readout (scores spread by " +
                  fixed(spread, 2) + " of the best over the range tried, at least " +
                  fixed(options.min_contrast, 2) +
                  " needed): turn in place, speeding up and slowing down";
    return out;
  }
  const double edge = half * options.coarse_step_s;
  if (std::abs(coarse_best) >= edge - 1e-9) {
    out.summary = "cannot: the best readout is at the end of the range tried (" +
                  fixed(coarse_best) + " s of +-" + fixed(options.max_s) +
                  " s): the frames translate, or the camera reads out longer";
    return out;
  }
  for (double r = coarse_best - options.coarse_step_s; r <= coarse_best + options.coarse_step_s + 1e-9;
       r += options.fine_step_s) {
    if (!score(r)) {
      out.summary = "cannot: too few frame pairs tracked at readout " + fixed(r) + " s";
      return out;
    }
  }
  const auto [r0, s0] = best();
  const double h = options.fine_step_s;
  const auto left = score(r0 - h), right = score(r0 + h);
  double estimate = r0;
  if (left && right) {
    const double curvature = *left + *right - 2.0 * s0;
    if (curvature > 0.0) estimate = r0 + 0.5 * h * (*left - *right) / curvature;
  }
  const double ends = std::min(out.curve.front().second, out.curve[2 * half].second);
  const double contrast = (ends - s0) / std::max(s0, std::numeric_limits<double>::min());
  if (!(contrast >= options.min_contrast)) {
    out.summary = "cannot: the frames hardly depend on the readout (score contrast " +
                  fixed(contrast, 2) + ", at least " + fixed(options.min_contrast, 2) +
                  " needed): turn in place, speeding up and slowing down";
    return out;
  }
  out.found = true;
  out.readout_s = std::clamp(estimate, -options.max_s, options.max_s);
  out.summary = "readout " + fixed(out.readout_s) + " s from " + std::to_string(fewest_pairs) +
                "+ frame pairs at " + std::to_string(out.curve.size()) +
                " readouts (score contrast " + fixed(contrast, 2) + ")";
  return out;
}

}  // namespace omnipose::calibrate
