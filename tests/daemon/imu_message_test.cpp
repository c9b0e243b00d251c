// omnipose.imu_t as the daemon will receive it (src/daemon/imu_message.hpp): a message
// encoded by LCM's own generated code decodes to its sample; bytes that are not one, or a
// message whose values are not readings, are refused naming what is wrong.
#include "daemon/imu_message.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "omnipose/imu_t.hpp"
#include "omnipose/pose_t.hpp"

using ::testing::HasSubstr;

namespace omnipose::daemon {
namespace {

template <typename Message>
std::vector<std::uint8_t> encode(const Message& m) {
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(m.getEncodedSize()));
  EXPECT_EQ(m.encode(bytes.data(), 0, static_cast<int>(bytes.size())), static_cast<int>(bytes.size()));
  return bytes;
}

imu_t sample() {
  imu_t m;
  m.utime = 1234567890123;
  m.gyro[0] = 0.125;
  m.gyro[1] = -2.5;
  m.gyro[2] = 35.0;
  m.accel[0] = m.accel[1] = m.accel[2] = std::numeric_limits<double>::quiet_NaN();
  return m;
}

std::string errorOf(std::span<const std::uint8_t> bytes) {
  const auto r = decodeImuMessage(bytes);
  return r ? std::string() : std::string(r.error().message());
}

TEST(ImuMessage, DecodesTheSampleAnLcmPublisherEncoded) {
  const auto r = decodeImuMessage(encode(sample()));
  ASSERT_TRUE(r.has_value()) << r.error().message();
  EXPECT_DOUBLE_EQ(r->t, 1234567.890123);
  EXPECT_EQ(r->rate, Eigen::Vector3d(0.125, -2.5, 35.0));
}

TEST(ImuMessage, BytesThatAreNotOneMessageAreRefused) {
  const std::vector<std::uint8_t> bytes = encode(sample());
  EXPECT_THAT(errorOf({}), HasSubstr("0 bytes are not an omnipose.imu_t"));
  EXPECT_THAT(errorOf(std::span(bytes).first(bytes.size() - 1)), HasSubstr("are not an omnipose.imu_t"));
  std::vector<std::uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_THAT(errorOf(longer), HasSubstr("imu: 1 bytes after the omnipose.imu_t message"));
  pose_t pose{};
  EXPECT_THAT(errorOf(encode(pose)), HasSubstr("are not an omnipose.imu_t")) << "another type";
}

TEST(ImuMessage, ValuesThatAreNotReadingsAreRefused) {
  imu_t m = sample();
  m.utime = 0;
  EXPECT_THAT(errorOf(encode(m)), HasSubstr("imu: utime 0 is not a time"));
  m = sample();
  m.gyro[1] = std::numeric_limits<double>::infinity();
  EXPECT_THAT(errorOf(encode(m)), HasSubstr("imu: gyro[1] = inf rad/s is not a reading"));
  m = sample();
  m.gyro[2] = std::nan("");
  EXPECT_THAT(errorOf(encode(m)), HasSubstr("imu: gyro[2] = nan"));
  m = sample();
  m.gyro[0] = -101.0;
  EXPECT_THAT(errorOf(encode(m)), HasSubstr("gyro[0] = -101 rad/s"));
  m.gyro[0] = -100.0;
  EXPECT_EQ(errorOf(encode(m)), "") << "the range's end is a reading";
}

}  // namespace
}  // namespace omnipose::daemon
