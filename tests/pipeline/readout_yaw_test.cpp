// ReadoutYaw (src/pipeline/readout_yaw.hpp): yaws measured between the windows' mean capture
// times t_k + c become yaws between the timestamps t_k, against a heading known in closed
// form. Exact for a constant angular acceleration at uneven frame spacing, across lost
// frames and against a keyframe; nothing accumulates along the chain; roll and pitch
// untouched; a global shutter unchanged.
#include <gtest/gtest.h>

#include <cmath>
#include <optional>
#include <vector>

#include "omnipose/so3.hpp"
#include "pipeline/readout_yaw.hpp"

namespace omnipose {
namespace {

constexpr double kOffset = 0.0133;  // c: 0.4 of a 30 fps frame

/// Timestamps at about 30 fps, uneven (a camera's jitter).
std::vector<double> timestamps(int n) {
  std::vector<double> t;
  for (int k = 0; k < n; ++k) t.push_back(k / 30.0 + 0.004 * std::sin(1.7 * k));
  return t;
}

/// What a registration of frames a -> b reports: the heading's change between a + c and
/// b + c, about the camera's vertical, with a fixed tilt beside it.
Eigen::Matrix3d registered(double (*heading)(double), double a, double b,
                           const Eigen::Vector2d& tilt = Eigen::Vector2d::Zero()) {
  return rotationFromVector(
      Eigen::Vector3d(tilt.x(), tilt.y(), heading(b + kOffset) - heading(a + kOffset)));
}

double constantAcceleration(double t) { return 0.2 + 1.5 * t + 9.0 * t * t; }  // rad
double constantVelocity(double t) { return -0.4 + 2.1 * t; }
double varying(double t) { return 0.3 * std::sin(9.0 * t) + 1.2 * t; }

TEST(ReadoutYaw, AConstantAccelerationIsReadExactlyBetweenTimestamps) {
  const std::vector<double> t = timestamps(12);
  pipeline::ReadoutYaw yaw(kOffset);
  double chained = 0.0;
  for (std::size_t k = 1; k < t.size(); ++k) {
    const Eigen::Matrix3d R = yaw.betweenTimestamps(
        registered(constantAcceleration, t[k - 1], t[k]), t[k - 1], t[k]);
    const double got = rotationVector(R).z();
    const double truth = constantAcceleration(t[k]) - constantAcceleration(t[k - 1]);
    chained += got;
    if (k == 1) {
      // The chain's first pair takes the velocity as constant: off by c times the
      // velocity's change over the pair.
      EXPECT_NEAR(got, truth, 1.1 * kOffset * 18.0 * (t[1] - t[0])) << "pair 1";
      EXPECT_GT(std::abs(got - truth), 1e-4) << "pair 1 is not exact";
    } else if (k >= 3) {
      EXPECT_NEAR(got, truth, 1e-12) << "pair " << k;
    }
  }
  // The published headings are the chain's samples moved by their own offsets: the chained
  // error is the start's offset error alone, whatever the number of pairs.
  const double chain_error =
      chained - (constantAcceleration(t.back()) - constantAcceleration(t.front()));
  EXPECT_LT(std::abs(chain_error), kOffset * 18.0 * (t[1] - t[0])) << chain_error;
}

TEST(ReadoutYaw, AConstantVelocityIsLeftAsMeasured) {
  const std::vector<double> t = timestamps(8);
  pipeline::ReadoutYaw yaw(kOffset);
  for (std::size_t k = 1; k < t.size(); ++k) {
    const Eigen::Matrix3d in = registered(constantVelocity, t[k - 1], t[k]);
    const Eigen::Matrix3d out = yaw.betweenTimestamps(in, t[k - 1], t[k]);
    // The heading at a timestamp is the sample at t + c less c times the velocity; with
    // uneven spacing the measured yaw (over the same length of time) is already right.
    EXPECT_NEAR(rotationVector(out).z(), constantVelocity(t[k]) - constantVelocity(t[k - 1]),
                1e-12)
        << "pair " << k;
  }
}

TEST(ReadoutYaw, RollAndPitchAreLeftAlone) {
  const std::vector<double> t = timestamps(6);
  pipeline::ReadoutYaw yaw(kOffset);
  for (std::size_t k = 1; k < t.size(); ++k) {
    const Eigen::Vector2d tilt(0.004 * k, -0.003);
    const Eigen::Matrix3d out =
        yaw.betweenTimestamps(registered(varying, t[k - 1], t[k], tilt), t[k - 1], t[k]);
    const Eigen::Vector3d omega = rotationVector(out);
    EXPECT_NEAR(omega.x(), tilt.x(), 1e-12);
    EXPECT_NEAR(omega.y(), tilt.y(), 1e-12);
  }
}

TEST(ReadoutYaw, AVaryingTurnIsCloserThanTheMeasuredYaw) {
  // A turn whose rate swings at 1.4 Hz: the interpolated yaw is far closer to the truth
  // between timestamps than the yaw between the mean capture times.
  const std::vector<double> t = timestamps(40);
  pipeline::ReadoutYaw yaw(kOffset);
  double measured_sq = 0.0, interpolated_sq = 0.0;
  for (std::size_t k = 1; k < t.size(); ++k) {
    const Eigen::Matrix3d in = registered(varying, t[k - 1], t[k]);
    const double truth = varying(t[k]) - varying(t[k - 1]);
    const double got = rotationVector(yaw.betweenTimestamps(in, t[k - 1], t[k])).z();
    if (k < 3) continue;
    measured_sq += std::pow(rotationVector(in).z() - truth, 2);
    interpolated_sq += std::pow(got - truth, 2);
  }
  EXPECT_LT(interpolated_sq, 0.01 * measured_sq)
      << "RMS " << std::sqrt(interpolated_sq) << " against " << std::sqrt(measured_sq);
}

TEST(ReadoutYaw, RegistrationsAgainstAKeyframeContinueTheChainFromItsAnchor) {
  // Frames 0-3 frame to frame; frame 3 becomes a keyframe, and frames 4-9 are registered
  // against it (each against frame 3, not against the one before).
  const std::vector<double> t = timestamps(10);
  pipeline::ReadoutYaw yaw(kOffset);
  for (std::size_t k = 1; k <= 3; ++k)
    (void)yaw.betweenTimestamps(registered(constantAcceleration, t[k - 1], t[k]), t[k - 1], t[k]);
  const pipeline::ReadoutYaw::Anchor key = yaw.anchor();
  EXPECT_EQ(key.time, t[3]);
  for (std::size_t k = 4; k < t.size(); ++k) {
    const Eigen::Matrix3d R =
        yaw.betweenTimestamps(registered(constantAcceleration, t[3], t[k]), t[3], t[k], &key);
    EXPECT_NEAR(rotationVector(R).z(), constantAcceleration(t[k]) - constantAcceleration(t[3]),
                1e-12)
        << "frame " << k << " against the keyframe";
  }
  // An anchor of an earlier chain means nothing to this one: a new chain, taken at
  // constant velocity.
  yaw.reset();
  (void)yaw.betweenTimestamps(registered(constantAcceleration, t[0], t[1]), t[0], t[1]);
  const Eigen::Matrix3d stale = registered(constantAcceleration, t[3], t[9]);
  EXPECT_NEAR(rotationVector(yaw.betweenTimestamps(stale, t[3], t[9], &key)).z(),
              rotationVector(stale).z(), 1e-12);
}

TEST(ReadoutYaw, ASecondRegistrationAgainstAnAnchorIsMovedAsTheChainWouldWithoutChangingIt) {
  // Frames chained frame to frame; each from frame 4 on is registered against keyframe 2 as
  // well (Odometry's anchoring): that yaw between the timestamps is exact, and the chain
  // goes on as if the second registration had not been made.
  const std::vector<double> t = timestamps(10);
  pipeline::ReadoutYaw yaw(kOffset), alone(kOffset);
  pipeline::ReadoutYaw::Anchor key;
  for (std::size_t k = 1; k < t.size(); ++k) {
    const Eigen::Matrix3d pair = registered(constantAcceleration, t[k - 1], t[k]);
    const double chained = rotationVector(yaw.betweenTimestamps(pair, t[k - 1], t[k])).z();
    EXPECT_EQ(chained, rotationVector(alone.betweenTimestamps(pair, t[k - 1], t[k])).z());
    if (k == 2) {
      key = yaw.anchor();
      EXPECT_FALSE(yaw.againstAnchor(pair, key).has_value()) << "the last frame itself";
    }
    if (k >= 4) {
      const std::optional<Eigen::Matrix3d> R =
          yaw.againstAnchor(registered(constantAcceleration, t[2], t[k]), key);
      ASSERT_TRUE(R.has_value()) << "frame " << k;
      EXPECT_NEAR(rotationVector(*R).z(), constantAcceleration(t[k]) - constantAcceleration(t[2]),
                  1e-12)
          << "frame " << k << " against the keyframe";
    }
  }
  // An anchor of another chain, or a chain without a pair yet: no answer.
  yaw.reset();
  yaw.begin(t[9]);
  EXPECT_FALSE(yaw.againstAnchor(Eigen::Matrix3d::Identity(), key).has_value());
  // A global shutter: the rotation as registered.
  const pipeline::ReadoutYaw global(0.0);
  const Eigen::Matrix3d R = registered(constantAcceleration, t[2], t[5]);
  EXPECT_TRUE(global.againstAnchor(R, key)->isApprox(R));
}

TEST(ReadoutYaw, ASegmentsFirstFrameServesAsKeyframeFromTheStart) {
  // The segment's first frame is the keyframe of every later frame (a robot turning in
  // place keeps it in reach): its anchor, taken before any pair, gets its offset from the
  // chain's first pair.
  const std::vector<double> t = timestamps(10);
  pipeline::ReadoutYaw yaw(kOffset);
  yaw.begin(t[0]);
  const pipeline::ReadoutYaw::Anchor first = yaw.anchor();
  EXPECT_TRUE(std::isnan(first.offset));
  double previous = 0.0;
  for (std::size_t k = 1; k < t.size(); ++k) {
    const double from_first = rotationVector(yaw.betweenTimestamps(
        registered(constantAcceleration, t[0], t[k]), t[0], t[k], &first)).z();
    if (k >= 3) {
      EXPECT_NEAR(from_first - previous, constantAcceleration(t[k]) - constantAcceleration(t[k - 1]),
                  1e-12)
          << "frame " << k;
    }
    previous = from_first;
  }
}

TEST(ReadoutYaw, AGapKeepsTheChainAndAnotherReferenceStartsANewOne) {
  const std::vector<double> t = timestamps(10);
  pipeline::ReadoutYaw yaw(kOffset);
  for (std::size_t k = 1; k < 5; ++k)
    (void)yaw.betweenTimestamps(registered(constantAcceleration, t[k - 1], t[k]), t[k - 1], t[k]);
  // Frames 5 and 6 lost: the pair 4 -> 7 still follows the last one, and its sample of the
  // heading at t[7] + c belongs to the chain (exact for a constant acceleration).
  const Eigen::Matrix3d across = registered(constantAcceleration, t[4], t[7]);
  EXPECT_NEAR(rotationVector(yaw.betweenTimestamps(across, t[4], t[7])).z(),
              constantAcceleration(t[7]) - constantAcceleration(t[4]), 1e-12);
  // A pair from an older frame without its anchor starts a new chain: like any chain's
  // first pair it is taken at constant velocity, so returned as registered.
  const Eigen::Matrix3d from_older = registered(constantAcceleration, t[3], t[8]);
  EXPECT_NEAR(rotationVector(yaw.betweenTimestamps(from_older, t[3], t[8])).z(),
              rotationVector(from_older).z(), 1e-12);
  // A reset does the same.
  yaw.reset();
  const Eigen::Matrix3d next = registered(constantAcceleration, t[8], t[9]);
  EXPECT_NEAR(rotationVector(yaw.betweenTimestamps(next, t[8], t[9])).z(),
              rotationVector(next).z(), 1e-12);
  // No offset (a global shutter), or no time between the frames: unchanged, bit for bit.
  pipeline::ReadoutYaw global(0.0);
  for (std::size_t k = 1; k < t.size(); ++k) {
    const Eigen::Matrix3d in = registered(varying, t[k - 1], t[k]);
    EXPECT_EQ(global.betweenTimestamps(in, t[k - 1], t[k]), in);
  }
  const Eigen::Matrix3d in = registered(varying, t[1], t[2]);
  EXPECT_EQ(yaw.betweenTimestamps(in, t[2], t[2]), in);
}

}  // namespace
}  // namespace omnipose
