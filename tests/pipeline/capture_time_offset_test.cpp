// CaptureTimeOffset (src/pipeline/capture_time_offset.hpp): readings of the images' yaw less
// the gyro's against the change of the yaw rate, as a turning robot gives them (ramps of the
// yaw rate up and down), with image noise and a bias the gyro's estimate has not removed.
// The offset is found and the pairs corrected with it are read back uncorrected; pure noise
// gives no offset; a pair people moved does not set it; wild readings are refused; the offset
// stays bounded.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>

#include "pipeline/capture_time_offset.hpp"

namespace omnipose {
namespace {

using pipeline::CaptureTimeOffset;

/// The yaw rate change of pair k (rad/s): ramps up for 6 pairs, held for 4, ramped down.
double rateChange(int k) {
  const int phase = k % 20;
  if (phase < 6) return 0.5;
  if (phase < 10) return 0.0;
  if (phase < 16) return -0.5;
  return 0.0;
}

/// Feeds `pairs` readings of a true offset `delta` (seconds), each corrected with the
/// estimate so far as the pipeline does, with white image noise of `noise_rad` and a bias
/// residue of `bias_rad` per pair; pair `wrong` (if any) is off by `wrong_rad` besides.
/// Returns the estimator.
CaptureTimeOffset feed(double delta, double noise_rad, double bias_rad, int pairs,
                       unsigned seed = 3, int wrong = -1, double wrong_rad = 0.0) {
  CaptureTimeOffset estimator;
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, noise_rad);
  for (int k = 0; k < pairs; ++k) {
    const double x = rateChange(k), used = estimator.offset();
    const double beyond =
        (delta - used) * x + bias_rad + noise(rng) + (k == wrong ? wrong_rad : 0.0);
    estimator.update(beyond, x, used);
  }
  return estimator;
}

TEST(CaptureTimeOffset, FindsTheOffsetTheYawWasCapturedAt) {
  // 0.08 ms, as on the park photo, under 0.03 mrad of image noise per pair and a bias
  // residue of 0.1 mrad per pair (3 mrad/s).
  const CaptureTimeOffset e = feed(-0.08e-3, 0.03e-3, 0.1e-3, 300);
  EXPECT_GE(e.readings(), 295);  // a Gaussian reading beyond 3 sigmas is left out too
  EXPECT_NEAR(e.offset(), -0.08e-3, 0.01e-3);
  // Noise-free it is the offset itself, up to the ridge's pull in the first pairs.
  EXPECT_NEAR(feed(0.05e-3, 0.0, 0.0, 300).offset(), 0.05e-3, 0.002e-3);
}

TEST(CaptureTimeOffset, NoiseAloneGivesNoOffset) {
  // Texture spread evenly (indoors): the readings are noise (0.04 mrad per pair, 60 pairs:
  // a standard error of 0.013 ms). An estimate within one standard error of 0 is not used,
  // so most runs use none; the others stay within 2.5 standard errors (at a rate change of
  // 0.5 rad/s, 0.016 mrad of yaw: well under the noise).
  int unused = 0;
  for (unsigned seed = 1; seed <= 20; ++seed) {
    const CaptureTimeOffset e = feed(0.0, 0.04e-3, 0.0, 60, seed);
    EXPECT_LT(std::abs(e.offset()), 0.033e-3) << "seed " << seed;
    if (e.offset() == 0.0) ++unused;
  }
  EXPECT_GE(unused, 10);
  // Before any reading, and on the first few: nothing.
  EXPECT_EQ(CaptureTimeOffset{}.offset(), 0.0);
  EXPECT_EQ(feed(-0.08e-3, 0.0, 0.0, CaptureTimeOffset::kWarmUp - 1).offset(), 0.0);
}

TEST(CaptureTimeOffset, APairPeopleMovedDoesNotSetIt) {
  // Indoors (no offset), a pair 0.55 mrad off while the rate changes by 0.5 rad/s (people
  // walking by in a turn): alone it would say 1 ms. Among the first readings or after them,
  // it is left out.
  for (const int wrong : {10, 25, 45}) {
    const CaptureTimeOffset e = feed(0.0, 0.03e-3, 0.0, 60, 5, wrong, -0.55e-3);
    EXPECT_LT(std::abs(e.offset()), 0.02e-3) << "pair " << wrong;
    EXPECT_EQ(e.readings(), wrong < CaptureTimeOffset::kWarmUp ? 60 : 59) << "pair " << wrong;
  }
}

TEST(CaptureTimeOffset, RefusesReadingsThatAreNoCaptureTime) {
  CaptureTimeOffset e = feed(-0.08e-3, 0.0, 0.0, 100);
  const double before = e.offset();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_FALSE(e.update(nan, 0.5, before));
  EXPECT_FALSE(e.update(0.0, nan, before));
  EXPECT_FALSE(e.update(0.0, 0.5, std::numeric_limits<double>::infinity()));
  // A pair the images got wrong by 3 mrad.
  EXPECT_FALSE(e.update(3e-3, 0.5, before));
  EXPECT_EQ(e.readings(), 100);
  EXPECT_EQ(e.offset(), before);
}

TEST(CaptureTimeOffset, StaysWithinWhatTextureCanMove) {
  // Readings that would say 5 ms (a clock offset, not texture) are held at kMaxOffsetS.
  CaptureTimeOffset e;
  for (int k = 0; k < 200; ++k) {
    const double x = rateChange(k) * 0.2;  // 0.1 rad/s: 0.5 mrad per pair at 5 ms
    e.update(5e-3 * x, x, 0.0);
  }
  EXPECT_EQ(e.offset(), CaptureTimeOffset::kMaxOffsetS);
}

}  // namespace
}  // namespace omnipose
