#include "omnipose/ring_consensus.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numbers>
#include <random>
#include <tuple>
#include <utility>
#include <vector>

namespace omnipose {
namespace {

constexpr int kWindows = 55;  // the default pipeline's ring (1100 columns, step 20)

double azimuth(int k) { return 2.0 * std::numbers::pi * (k + 0.5) / kWindows; }

bool inArc(double theta, double from_deg, double to_deg) {
  const double deg = theta * 180.0 / std::numbers::pi;
  return deg >= from_deg && deg <= to_deg;
}

/// A ring of windows' du: yaw `yaw_px`, the translation's harmonic (b sin + c cos) scaled by
/// each window's inverse depth, Gaussian noise.
struct Ring {
  double yaw_px = 0.0, b = 0.0, c = 0.0, noise_px = 0.02;
  std::vector<double> inverse_depth = std::vector<double>(kWindows, 1.0);

  std::vector<RingSample> samples(std::mt19937& rng) const {
    std::normal_distribution<double> noise(0.0, noise_px);
    std::vector<RingSample> s(kWindows);
    for (int k = 0; k < kWindows; ++k) {
      const double t = azimuth(k), lambda = inverse_depth[k];
      s[k].theta = t;
      s[k].du_px = yaw_px + lambda * (b * std::sin(t) + c * std::cos(t)) + noise(rng);
    }
    return s;
  }
};

std::vector<std::uint8_t> flagsOf(const std::vector<RingSample>& s, int& flagged,
                                  const RingConsensusOptions& options = {}) {
  std::vector<std::uint8_t> flags(s.size(), 7);
  std::vector<double> work(3 * s.size());
  flagged = flagInconsistentWindows(s, options, flags, work);
  return flags;
}

// The failing render of the people benchmark, as the fit saw it (docs/results/ANALYSIS.md):
// a robot turning in place, two groups of people (112-160 and 218-275 degrees, 29 % of the
// ring) 4.5 px against the background. A translation with free depths explains them; the
// consensus does not, and flags exactly them.
TEST(RingConsensus, PeopleAcrossAThirdOfTheRingAreFlaggedAndNothingElse) {
  std::mt19937 rng(5);
  Ring ring;
  ring.yaw_px = 3.1;
  std::vector<RingSample> s = ring.samples(rng);
  for (RingSample& q : s)
    if (inArc(q.theta, 112, 160) || inArc(q.theta, 218, 275)) q.du_px -= 4.5;
  int flagged = 0;
  const std::vector<std::uint8_t> flags = flagsOf(s, flagged);
  int people = 0;
  for (int k = 0; k < kWindows; ++k) {
    const bool person = inArc(s[k].theta, 112, 160) || inArc(s[k].theta, 218, 275);
    people += person;
    EXPECT_EQ(flags[k], person ? 1 : 0) << "window " << k << " at " << s[k].theta;
  }
  EXPECT_EQ(flagged, people);
  EXPECT_GE(people, 15);
}

// A robot driving in a box room: depths from 0.4 to 2.8 times the mean (walls near and far),
// which no single depth fits, every window explained by its own: none is flagged.
TEST(RingConsensus, ParallaxOfAStaticRoomIsNotFlagged) {
  for (const unsigned seed : {1u, 2u, 3u}) {
    std::mt19937 rng(seed);
    Ring ring;
    ring.yaw_px = 0.3;
    ring.b = -2.5;  // driving towards azimuth 0: du = -lambda tau sin(theta)
    for (int k = 0; k < kWindows; ++k) {
      // A 6 x 5 m room seen from off its centre: inverse distance to the walls.
      const double t = azimuth(k), x = 3.0 - 0.8, y = 2.5 + 0.4;
      const double dx = std::cos(t), dy = std::sin(t);
      const double to_x = dx > 0 ? (6.0 - x) / dx : x / -dx, to_y = dy > 0 ? (5.0 - y) / dy : y / -dy;
      ring.inverse_depth[k] = 2.2 / std::min(to_x, to_y);
    }
    const std::vector<RingSample> s = ring.samples(rng);
    int flagged = -1;
    const std::vector<std::uint8_t> flags = flagsOf(s, flagged);
    EXPECT_EQ(flagged, 0) << "seed " << seed;
    for (int k = 0; k < kWindows; ++k) EXPECT_EQ(flags[k], 0) << "window " << k;
  }
}

// While the robot drives, a person walking against the direction a static object at that
// azimuth would move (no depth explains it) is flagged, away from the direction of travel;
// the room is not.
TEST(RingConsensus, APersonMovingAgainstTheParallaxIsFlaggedWhileDriving) {
  std::mt19937 rng(11);
  Ring ring;
  ring.b = -2.0;
  std::vector<RingSample> s = ring.samples(rng);
  // At 60-90 degrees a static window's du is -2 lambda sin(theta) < 0 for every depth; with
  // the person's +3 px it is positive. (A smaller offset only reads as a farther depth.)
  for (RingSample& q : s)
    if (inArc(q.theta, 60, 90)) q.du_px += 3.0;
  int flagged = 0;
  const std::vector<std::uint8_t> flags = flagsOf(s, flagged);
  for (int k = 0; k < kWindows; ++k)
    EXPECT_EQ(flags[k], inArc(s[k].theta, 60, 90) ? 1 : 0) << "window " << k;
}

// Within 45 degrees of the direction of travel du is not tested (it tells the direction
// there, not the depth) while the fit before has not found the axis; turning in place there
// is no such axis and every window is tested.
TEST(RingConsensus, NearTheDirectionOfTravelDuIsNotTested) {
  for (const bool driving : {true, false}) {
    SCOPED_TRACE(driving ? "driving" : "turning in place");
    std::mt19937 rng(16);
    Ring ring;
    ring.yaw_px = driving ? 0.0 : 2.0;
    ring.b = driving ? -2.0 : 0.0;
    std::vector<RingSample> s = ring.samples(rng);
    // Window 1 (10 degrees): under the driving, its du is -2 lambda sin(10 deg) <= 0 for
    // every depth; +1.5 px makes it positive.
    s[1].du_px += 1.5;
    int flagged = 0;
    const std::vector<std::uint8_t> flags = flagsOf(s, flagged);
    EXPECT_EQ(flags[1], driving ? 0 : 1);
    EXPECT_EQ(flagged, driving ? 0 : 1);
  }
}

// When the previous fit's axis agrees with the consensus's (either sign, within 10 deg),
// du is tested from 10 deg of the axis: a person crossing in front of the robot at 16-23 deg
// is flagged. A previous axis 40 deg away, or none, leaves the 45-deg band.
TEST(RingConsensus, NearTheDirectionOfTravelDuIsTestedWhenThePreviousFitAgrees) {
  constexpr double kPi = std::numbers::pi;
  struct Case {
    double previous_axis;
    bool judged;
  };
  // b sin + c cos with b = -2, c = 0: the axis atan2(c, b) is pi, or 0 for the other sign.
  for (const Case& c : {Case{kPi, true}, Case{0.1, true}, Case{kPi - 40 * kPi / 180, false},
                        Case{std::numeric_limits<double>::quiet_NaN(), false}}) {
    SCOPED_TRACE(c.previous_axis);
    std::mt19937 rng(17);
    Ring ring;
    ring.b = -2.0;
    std::vector<RingSample> s = ring.samples(rng);
    // Windows 2 and 3 (16 and 23 deg): a static window's du is -2 lambda sin(theta) < 0 there.
    s[2].du_px += 1.5;
    s[3].du_px += 1.5;
    // Window 1 (10 deg, inside the narrow band) likewise: never tested.
    s[1].du_px += 1.5;
    RingConsensusOptions options;
    options.previous_axis_rad = c.previous_axis;
    int flagged = 0;
    const std::vector<std::uint8_t> flags = flagsOf(s, flagged, options);
    EXPECT_EQ(flags[2], c.judged ? 1 : 0);
    EXPECT_EQ(flags[3], c.judged ? 1 : 0);
    EXPECT_EQ(flags[1], 0);
    EXPECT_EQ(flagged, c.judged ? 2 : 0);
  }
}

// Noise alone is not flagged: heavy-tailed (as a blurred JPEG 75 lens gives), every sample
// under the floor, with the floor at its 0.1 px least (a sharp lens, noise of a few
// hundredths of a pixel) and at its 0.5 px most (a blurred one, noise of a tenth).
TEST(RingConsensus, NoiseAloneIsNotFlagged) {
  for (const auto& [scale, bound] : {std::pair{0.02, 0.09}, std::pair{0.125, 0.45}}) {
    for (const unsigned seed : {13u, 14u, 15u, 16u, 17u, 18u}) {
      std::mt19937 rng(seed);
      std::student_t_distribution<double> tails(3.0);
      Ring ring;
      ring.yaw_px = 2.0;
      ring.noise_px = 0.0;
      std::vector<RingSample> s = ring.samples(rng);
      for (RingSample& q : s) q.du_px += std::clamp(scale * tails(rng), -bound, bound);
      int flagged = -1;
      flagsOf(s, flagged);
      EXPECT_EQ(flagged, 0) << "noise scale " << scale << ", seed " << seed;
    }
  }
}

// Turning in place the ring agrees within its noise, and the windows a person covers in part
// are pulled a few tenths of a pixel: the people benchmark's park render of two people
// walking with the turn, one frame pair as the consensus saw it (docs/results/ANALYSIS.md).
// Each is flagged, though under the 0.5 px that judges a driving robot's ring, and though
// its weaker peak widens its threshold; the background is not.
TEST(RingConsensus, WindowsAPersonCoversInPartAreFlaggedWhileTurning) {
  std::mt19937 rng(21);
  Ring ring;
  ring.yaw_px = 0.41;
  ring.noise_px = 0.008;
  std::vector<RingSample> s = ring.samples(rng);
  for (RingSample& q : s) q.confidence = 0.95;
  // window: du's pull by the person, px, and the peak's confidence
  const std::vector<std::tuple<int, double, double>> people{
      {26, -0.22, 0.80}, {27, -0.50, 0.70}, {28, -0.55, 0.64}, {29, -0.28, 0.81},
      {47, -0.14, 0.81}, {48, -0.25, 0.70}, {49, -0.51, 0.48}, {50, -0.65, 0.64},
      {51, -0.22, 0.77}};
  for (const auto& [k, pull, confidence] : people) {
    s[k].du_px += pull;
    s[k].confidence = confidence;
  }
  int flagged = 0;
  const std::vector<std::uint8_t> flags = flagsOf(s, flagged);
  for (const auto& [k, pull, confidence] : people) EXPECT_EQ(flags[k], 1) << "window " << k;
  EXPECT_EQ(flagged, static_cast<int>(people.size()));
}

// Windows overlap their neighbours, so the one beside a person is covered in part and pulled
// part of the way. Turning in place (noise 0.01 px, the threshold at its 0.1 px floor), a
// person walking against the turn, 4.5 px off over windows 20-24, pulls windows 19 and 25 by
// 0.07 px: under the threshold, over neighbour_fraction (0.3) of it, so they are left out with
// the person. The same pull on a window beside no flagged one (40) stays, and so do the
// neighbours of a single window whose peak erred by 1 px (10), which agree with the ring.
// With neighbour_fraction 0 only the person and the single window are flagged.
TEST(RingConsensus, AWindowBesideAPersonIsLeftOutAtAFractionOfItsThreshold) {
  std::mt19937 rng(23);
  Ring ring;
  ring.yaw_px = 1.5;
  ring.noise_px = 0.01;
  std::vector<RingSample> s = ring.samples(rng);
  for (int k = 20; k <= 24; ++k) s[k].du_px -= 4.5;
  s[19].du_px -= 0.07;
  s[25].du_px -= 0.07;
  s[40].du_px -= 0.07;
  s[10].du_px += 1.0;
  int flagged = 0;
  const std::vector<std::uint8_t> flags = flagsOf(s, flagged);
  for (int k = 0; k < kWindows; ++k) {
    const bool out = (k >= 19 && k <= 25) || k == 10;
    EXPECT_EQ(flags[k], out ? 1 : 0) << "window " << k;
  }
  EXPECT_EQ(flagged, 8);

  RingConsensusOptions without;
  without.neighbour_fraction = 0.0;
  const std::vector<std::uint8_t> strict = flagsOf(s, flagged, without);
  EXPECT_EQ(flagged, 6);
  EXPECT_EQ(strict[19], 0);
  EXPECT_EQ(strict[25], 0);
  EXPECT_EQ(strict[22], 1);
  EXPECT_EQ(strict[10], 1);
}

// A window with a weaker peak than the ring's median is judged with a threshold widened by
// the median confidence over its own: turning in place (the floor 0.1 px), a plain wall's
// window at 0.25 of the median confidence 0.3 px off (its shift as uncertain as that) stays,
// the same offset with a median peak is flagged, and a person 4.5 px off is flagged even with
// a peak that weak. A confidence that is not above 0 or not finite counts as the median.
TEST(RingConsensus, AWeakPeakIsJudgedWithAWiderThreshold) {
  std::mt19937 rng(19);
  Ring ring;
  ring.yaw_px = 2.0;
  std::vector<RingSample> s = ring.samples(rng);
  for (RingSample& q : s) q.confidence = 0.6;
  const int weak = 10, median_peak = 30, person = 45, unknown = 50, not_finite = 52;
  s[weak].du_px += 0.3;
  s[weak].confidence = 0.15;  // threshold 0.1 px x 4
  s[median_peak].du_px += 0.3;
  s[person].du_px += 4.5;
  s[person].confidence = 0.15;
  s[unknown].du_px += 0.3;
  s[unknown].confidence = 0.0;
  s[not_finite].du_px += 0.3;
  s[not_finite].confidence = std::numeric_limits<double>::quiet_NaN();
  int flagged = 0;
  const std::vector<std::uint8_t> flags = flagsOf(s, flagged);
  EXPECT_EQ(flags[weak], 0);
  EXPECT_EQ(flags[median_peak], 1);
  EXPECT_EQ(flags[person], 1);
  EXPECT_EQ(flags[unknown], 1);
  EXPECT_EQ(flags[not_finite], 1);
  EXPECT_EQ(flagged, 4);
  // A stronger peak than the median's is not judged more strictly: 0.04 px stays.
  std::vector<RingSample> strong = ring.samples(rng);
  for (RingSample& q : strong) q.confidence = 0.6;
  strong[20].du_px += 0.04;
  strong[20].confidence = 1.0;
  flagsOf(strong, flagged);
  EXPECT_EQ(flagged, 0);
}

TEST(RingConsensus, TooFewWindowsFlagNothing) {
  std::mt19937 rng(14);
  std::vector<RingSample> s = Ring{}.samples(rng);
  s.resize(7);
  s[3].du_px += 10.0;
  int flagged = -1;
  const std::vector<std::uint8_t> flags = flagsOf(s, flagged);
  EXPECT_EQ(flagged, 0);
  for (std::uint8_t f : flags) EXPECT_EQ(f, 0);
}

// A too small work buffer is refused, not overrun.
TEST(RingConsensus, ShortWorkBufferFlagsNothing) {
  std::mt19937 rng(15);
  std::vector<RingSample> s = Ring{}.samples(rng);
  s[3].du_px += 10.0;
  std::vector<std::uint8_t> flags(s.size(), 1);
  std::vector<double> work(3 * s.size() - 1);
  EXPECT_EQ(flagInconsistentWindows(s, RingConsensusOptions{}, flags, work), 0);
  for (std::uint8_t f : flags) EXPECT_EQ(f, 0);
}

}  // namespace
}  // namespace omnipose
