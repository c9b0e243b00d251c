#pragma once
/// \file capture_time_offset.hpp
/// When the images' yaw was captured, measured against the gyro (private to the core library;
/// DESIGN.md section 3, "Rolling shutter with a gyro").
///
/// With a rolling shutter and a gyro each window's turn within its frame is read at one
/// capture time, the taper-weighted mean of its pixels'. The correlation weighs the pixels by
/// their texture instead: where the texture sits in one part of the band (a horizon under a
/// bare sky) the windows' yaw is captured `delta` seconds off the times the model reads, and a
/// pair's yaw is then off by delta times the change of the yaw rate between its two frames
/// (0.06-0.1 ms, a quarter of the yaw error, on a park photo; about 0 indoors).
///
/// The gyro measures that change of rate, and the images' yaw less the gyro's is delta times
/// it plus the gyro's bias and noise: each pair the images measured well gives a reading.
/// The estimate is the regression of those readings on the rate change (with an intercept:
/// what is left of the bias), exponentially forgetting (kForget per pair), shrunk towards 0 by
/// kRidge and by its own standard error (an estimate within one standard error of 0 is not
/// used: indoors it would only add noise), and bounded by kMaxOffsetS. None is used before
/// kWarmUp readings; those are fitted together and the ones beyond kMaxSigmas of their fit
/// left out, and after them a reading beyond kMaxSigmas of the regression so far is not used
/// (a pair that people walking by or a glitch moved). Each reading states the offset its pair
/// was corrected with, so the regression sees the uncorrected yaw.
///
/// Realtime: no allocation, never throws.

#include <array>
#include <cmath>
#include <cstdint>
#include <utility>

namespace omnipose::pipeline {

class CaptureTimeOffset {
 public:
  /// Memory of the regression per pair (200 pairs, 7 s at 30 fps).
  static constexpr double kForget = 0.995;
  /// The regression's ridge, (rad/s)^2: about a second of pairs whose yaw rate changes by
  /// 0.1 rad/s, so that the first few readings cannot set it.
  static constexpr double kRidge = 0.3;
  /// No texture moves a window's capture time further than this, seconds.
  static constexpr double kMaxOffsetS = 0.5e-3;
  /// A reading whose yaw differs from the gyro's by more than this is no capture time (a
  /// pair the images got wrong, or a bias not yet known), radians.
  static constexpr double kMaxReadingRad = 2e-3;
  /// Readings before any offset is used (a second at 30 fps).
  static constexpr int kWarmUp = 30;
  /// A reading further than this many standard deviations from the regression is not used.
  static constexpr double kMaxSigmas = 3.0;

  /// One pair: `beyond_rad`, the images' yaw less the gyro's between the two timestamps
  /// (radians, about the camera's z axis, the pair corrected with `used_offset_s`), and
  /// `rate_change`, the gyro's yaw rate at the current timestamp less the one at the
  /// reference's (rad/s). False when not used (not finite, beyond kMaxReadingRad).
  bool update(double beyond_rad, double rate_change, double used_offset_s);
  /// The offset to read the windows' yaw at, seconds after the model's capture times
  /// (0 before any reading, and while it is not told from 0).
  double offset() const { return offset_; }
  /// Readings used so far (the first kWarmUp all counted, outliers or not).
  std::int64_t readings() const { return readings_; }

 private:
  /// A regression line y = intercept + slope x, its residuals' variance and the slope's.
  struct Line {
    double intercept = 0.0, slope = 0.0, scatter = 0.0, slope_variance = 0.0;
    /// Whether (x, y) lies within kMaxSigmas residual deviations of the line.
    bool holds(double x, double y) const {
      return std::abs(y - intercept - slope * x) <= kMaxSigmas * std::sqrt(scatter);
    }
  };
  /// Exponentially weighted sums (kForget per reading) of 1, x (rate change), y (uncorrected
  /// yaw), x^2, x y and y^2.
  struct Sums {
    double n = 0.0, sx = 0.0, sy = 0.0, sxx = 0.0, sxy = 0.0, syy = 0.0;
    void add(double x, double y, double weight);
    /// The ridge regression of y on x with an intercept (all zero before three readings).
    Line fit() const;
  };
  /// The first kWarmUp readings fitted, their outliers left out, into sums_.
  void startFromFirst();
  /// offset_ from `line`'s slope, shrunk and bounded.
  void setOffset(const Line& line);

  std::array<std::pair<double, double>, kWarmUp> first_{};  ///< (x, y) of the first readings
  Sums sums_;
  double offset_ = 0.0;
  std::int64_t readings_ = 0;
};

}  // namespace omnipose::pipeline
