// The IIO gyro reader (drivers/iio): the scan format (type parsing, the kernel's layout,
// decoding, scale) on its own, then IioGyro against the fake device (fake_iio_device.hpp),
// which follows the kernel's buffered interface and records every protocol violation:
// configuration, a full stream decoded to exact values, unplug and replug at another index,
// bad scans counted, and every start-up refusal named.

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <vector>

#include "fake_iio_device.hpp"
#include "iio/iio_gyro.hpp"
#include "iio/iio_scan.hpp"

using ::testing::HasSubstr;

namespace omnipose {
namespace {

using iio::ChannelRole;
using iio::ScanVerdict;
using testing::FakeIioDevice;

constexpr double kBmi160Scale = 0.000266;  // rad/s per LSB at ±500 deg/s, as the driver prints it

iio::ScanType type(const char* text) {
  const auto t = iio::parseScanType(text);
  EXPECT_TRUE(t.has_value()) << text;
  return t.value_or(iio::ScanType{});
}

TEST(IioScanType, ParsesTheKernelsFormat) {
  const iio::ScanType a = type("le:s16/16>>0\n");
  EXPECT_FALSE(a.big_endian);
  EXPECT_TRUE(a.is_signed);
  EXPECT_EQ(a.bits, 16);
  EXPECT_EQ(a.storage_bits, 16);
  EXPECT_EQ(a.repeat, 1);
  EXPECT_EQ(a.shift, 0);
  EXPECT_EQ(a.minRaw(), -32768);
  EXPECT_EQ(a.maxRaw(), 32767);
  const iio::ScanType b = type("be:u12/16>>4");
  EXPECT_TRUE(b.big_endian);
  EXPECT_FALSE(b.is_signed);
  EXPECT_EQ(b.bits, 12);
  EXPECT_EQ(b.shift, 4);
  EXPECT_EQ(b.minRaw(), 0);
  EXPECT_EQ(b.maxRaw(), 4095);
  // The widest of each sign (fuzz_iio_scan: an unsigned 63-bit maximum overflowed).
  EXPECT_EQ(type("le:u63/64>>0").maxRaw(), INT64_MAX);
  EXPECT_EQ(type("le:u63/64>>1").minRaw(), 0);
  EXPECT_EQ(type("le:s64/64>>0").maxRaw(), INT64_MAX);
  EXPECT_EQ(type("le:s64/64>>0").minRaw(), INT64_MIN);
  EXPECT_EQ(type("le:s63/64>>0").maxRaw(), (std::int64_t{1} << 62) - 1);
  EXPECT_EQ(type("le:s16/16X3>>0").repeat, 3);
  EXPECT_EQ(type("le:s64/64>>0").storageBytes(), 8);
  EXPECT_EQ(type("be:s24/32>>8").bits, 24);
}

TEST(IioScanType, RefusesWhatIsNotOne) {
  for (const char* bad : {"", "xx:s16/16>>0", "le:x16/16>>0", "le:s16/12>>0", "le:s17/16>>0",
                          "le:s12/16>>6", "le:s0/16>>0", "le:s16/16", "le:s16/16X0>>0",
                          "le:s16/16>>0 x", "le:s16/16>>16", "le:s-1/16>>0", "le:s16/16X>>0",
                          "le:u64/64>>0" /* fuzz_iio_scan: its raw value wrapped negative */}) {
    const auto t = iio::parseScanType(bad);
    EXPECT_FALSE(t.has_value()) << bad;
    if (!t) {
      EXPECT_THAT(std::string(t.error().c_str()), HasSubstr("scan type")) << bad;
    }
  }
}

std::vector<iio::ScanChannel> bmi160Channels(bool with_accel) {
  const iio::ScanType s16 = type("le:s16/16>>0"), s64 = type("le:s64/64>>0");
  std::vector<iio::ScanChannel> c = {{10, s64, ChannelRole::kTimestamp},
                                     {6, s16, ChannelRole::kRateZ},
                                     {4, s16, ChannelRole::kRateX},
                                     {5, s16, ChannelRole::kRateY}};
  if (with_accel)
    for (int i = 7; i <= 9; ++i) c.push_back({i, s16, ChannelRole::kOther});
  return c;
}

TEST(IioScanLayout, PlacesChannelsByIndexAlignedToTheirSize) {
  // Gyro and timestamp: 2+2+2, padded to 8 for the timestamp: 16 bytes.
  const auto a = iio::computeLayout(bmi160Channels(false));
  ASSERT_TRUE(a.has_value()) << a.error().c_str();
  EXPECT_EQ(a->rate[0].offset, 0u);
  EXPECT_EQ(a->rate[1].offset, 2u);
  EXPECT_EQ(a->rate[2].offset, 4u);
  EXPECT_EQ(a->timestamp.offset, 8u);
  EXPECT_EQ(a->scan_bytes, 16u);
  // With the accel: six s16 (12 bytes), the timestamp at 16, 24 bytes.
  const auto b = iio::computeLayout(bmi160Channels(true));
  ASSERT_TRUE(b.has_value());
  EXPECT_EQ(b->timestamp.offset, 16u);
  EXPECT_EQ(b->scan_bytes, 24u);
  // A 32-bit channel before a 16-bit gyro, an 8-bit one between: each aligned to its size.
  auto c = bmi160Channels(false);
  c.push_back({0, type("le:s8/8>>0"), ChannelRole::kOther});
  c.push_back({1, type("le:s32/32>>0"), ChannelRole::kOther});
  const auto d = iio::computeLayout(c);
  ASSERT_TRUE(d.has_value());
  EXPECT_EQ(d->rate[0].offset, 8u);  // s8 at 0, s32 at 4, x at 8
  EXPECT_EQ(d->timestamp.offset, 16u);
  EXPECT_EQ(d->scan_bytes, 24u);
}

TEST(IioScanLayout, RefusesIncompleteOrUnsupportedScans) {
  auto no_z = bmi160Channels(false);
  no_z.erase(no_z.begin() + 1);
  EXPECT_THAT(std::string(iio::computeLayout(no_z).error().c_str()), HasSubstr("in_anglvel_z"));
  auto no_ts = bmi160Channels(false);
  no_ts.erase(no_ts.begin());
  EXPECT_THAT(std::string(iio::computeLayout(no_ts).error().c_str()), HasSubstr("in_timestamp"));
  auto repeat = bmi160Channels(false);
  repeat[1].type = type("le:s16/16X3>>0");
  EXPECT_THAT(std::string(iio::computeLayout(repeat).error().c_str()), HasSubstr("repeats 3"));
  auto twice = bmi160Channels(false);
  twice[1].index = 4;
  EXPECT_THAT(std::string(iio::computeLayout(twice).error().c_str()), HasSubstr("scan index 4"));
  auto ts32 = bmi160Channels(false);
  ts32[0].type = type("le:s32/32>>0");
  EXPECT_THAT(std::string(iio::computeLayout(ts32).error().c_str()), HasSubstr("64-bit"));
}

TEST(IioScanDecode, ExtractsEndiannessSignAndShift) {
  const std::uint8_t bytes[] = {0xFF, 0xF0, 0x12, 0x34};
  EXPECT_EQ(iio::extractRaw(bytes, {type("be:s12/16>>4"), 0}), -1);       // 0xFFF
  EXPECT_EQ(iio::extractRaw(bytes, {type("be:u12/16>>4"), 0}), 4095);
  EXPECT_EQ(iio::extractRaw(bytes, {type("le:s16/16>>0"), 0}), -3841);    // 0xF0FF
  EXPECT_EQ(iio::extractRaw(bytes, {type("le:u16/16>>0"), 2}), 0x3412);
  EXPECT_EQ(iio::extractRaw(bytes, {type("be:u16/16>>0"), 2}), 0x1234);
  EXPECT_EQ(iio::extractRaw(bytes, {type("le:u8/8>>0"), 3}), 0x34);
  EXPECT_EQ(iio::extractRaw(bytes, {type("be:s32/32>>0"), 0}), static_cast<std::int32_t>(0xFFF01234));
}

/// One BMI160 scan (16 bytes) with x, y, z and the timestamp.
std::vector<std::uint8_t> scan16(std::int16_t x, std::int16_t y, std::int16_t z, std::int64_t t) {
  std::vector<std::uint8_t> s(16, 0xA5);
  const std::int16_t v[] = {x, y, z};
  for (int k = 0; k < 3; ++k) {
    s[2 * k] = static_cast<std::uint8_t>(v[k] & 0xFF);
    s[2 * k + 1] = static_cast<std::uint8_t>((v[k] >> 8) & 0xFF);
  }
  for (int i = 0; i < 8; ++i) s[8 + i] = static_cast<std::uint8_t>(static_cast<std::uint64_t>(t) >> (8 * i));
  return s;
}

TEST(IioScanDecode, ScalesAndJudgesEachScan) {
  const auto layout = iio::computeLayout(bmi160Channels(false)).value();
  iio::RateScale scale{{kBmi160Scale, kBmi160Scale, 0.001065}, {0.0, 0.0, 2.0}};
  const auto good = iio::decodeScan(scan16(1000, -2000, 3, 5'000'000'123), layout, scale, 0);
  EXPECT_EQ(good.verdict, ScanVerdict::kOk);
  EXPECT_EQ(good.timestamp_ns, 5'000'000'123);
  EXPECT_DOUBLE_EQ(good.sample.t, 5'000'000'123 * 1e-9);
  EXPECT_DOUBLE_EQ(good.sample.rate.x(), 1000 * kBmi160Scale);
  EXPECT_DOUBLE_EQ(good.sample.rate.y(), -2000 * kBmi160Scale);
  EXPECT_DOUBLE_EQ(good.sample.rate.z(), (3 + 2.0) * 0.001065);  // (raw + offset) * scale
  EXPECT_EQ(iio::decodeScan(scan16(1, 1, 1, 0), layout, scale, 0).verdict, ScanVerdict::kTimestampZero);
  EXPECT_EQ(iio::decodeScan(scan16(1, 1, 1, -5), layout, scale, 0).verdict, ScanVerdict::kTimestampZero);
  EXPECT_EQ(iio::decodeScan(scan16(1, 1, 1, 100), layout, scale, 100).verdict,
            ScanVerdict::kTimestampBackwards);
  EXPECT_EQ(iio::decodeScan(scan16(32767, 1, 1, 200), layout, scale, 100).verdict, ScanVerdict::kSaturated);
  EXPECT_EQ(iio::decodeScan(scan16(1, -32768, 1, 200), layout, scale, 100).verdict, ScanVerdict::kSaturated);
  EXPECT_EQ(iio::decodeScan(scan16(32766, -32767, 1, 200), layout, scale, 100).verdict, ScanVerdict::kOk);
  const auto s = scan16(1, 1, 1, 200);
  EXPECT_EQ(iio::decodeScan(std::span(s.data(), 15), layout, scale, 0).verdict, ScanVerdict::kTruncated);
}

TEST(IioScanDecode, ReadsSysfsNumbers) {
  EXPECT_DOUBLE_EQ(iio::parseSysfsNumber("0.000266316\n").value(), 0.000266316);
  EXPECT_DOUBLE_EQ(iio::parseSysfsNumber("-3").value(), -3.0);
  EXPECT_DOUBLE_EQ(iio::parseSysfsNumber(" 1.5e-3 ").value(), 1.5e-3);
  for (const char* bad : {"", "abc", "1.5x", "nan", "inf", "0x10"})
    EXPECT_FALSE(iio::parseSysfsNumber(bad).has_value()) << bad;
}

// ---- IioGyro on the fake device ---------------------------------------------------------

IioGyroOptions optionsFor(const FakeIioDevice::Config& c, const std::string& device = "bmi160") {
  IioGyroOptions o;
  o.device = device;
  o.sysfs_root = c.sysfs_root;
  o.dev_root = c.dev_root;
  return o;
}

/// Reads until `wanted` samples arrived or `reads` reads were made.
std::vector<GyroSample> readSamples(IioGyro& gyro, std::size_t wanted, std::size_t* bad = nullptr,
                                    int reads = 200) {
  std::vector<GyroSample> all, out(IioGyro::kMaxScansPerRead);
  for (int i = 0; i < reads && all.size() < wanted; ++i) {
    const auto r = gyro.read(out, 5);
    EXPECT_TRUE(r.has_value()) << r.error().c_str();
    if (!r) break;
    all.insert(all.end(), out.begin(), out.begin() + static_cast<std::ptrdiff_t>(r->samples));
    if (bad) *bad += r->bad;
  }
  return all;
}

/// A 200 Hz turn: raw rates that change per scan, on CLOCK_MONOTONIC from 5000 s of uptime.
std::array<std::int64_t, 3> rawAt(int k) { return {100 + k, -200 - 3 * k, 7 * (k % 50) - 150}; }
constexpr std::int64_t kT0 = 5'000'000'000'000;
constexpr std::int64_t kPeriod = 5'000'000;

TEST(IioGyro, ConfiguresTheDeviceAndDecodesAStreamExactly) {
  FakeIioDevice dev;
  IioGyro gyro(optionsFor(FakeIioDevice::Config{}), dev);
  const auto opened = gyro.open();
  ASSERT_TRUE(opened.has_value()) << opened.error().c_str();
  EXPECT_TRUE(gyro.warnings().empty());
  // The gyro and the timestamp enabled, the accel (left enabled by someone) cleared.
  for (const char* axis : {"x", "y", "z"}) {
    EXPECT_EQ(dev.attribute(std::string("scan_elements/in_anglvel_") + axis + "_en"), "1");
    EXPECT_EQ(dev.attribute(std::string("scan_elements/in_accel_") + axis + "_en"), "0");
  }
  EXPECT_EQ(dev.attribute("scan_elements/in_timestamp_en"), "1");
  EXPECT_EQ(dev.attribute("current_timestamp_clock"), "monotonic");
  EXPECT_EQ(dev.attribute("trigger/current_trigger"), "bmi160-dev0");
  EXPECT_EQ(dev.attribute("buffer/length"), "1024");
  EXPECT_EQ(dev.attribute("in_anglvel_sampling_frequency"), "100") << "left as it was";
  EXPECT_TRUE(dev.bufferEnabled());
  EXPECT_EQ(dev.scanBytes(), 16u);
  EXPECT_EQ(gyro.label(), "iio:device0 (bmi160)");
  EXPECT_EQ(gyro.describe(), "iio:device0 (bmi160), anglvel x,y,z le:s16/16>>0 x 0.000266 rad/s, "
                             "16-byte scans, clock monotonic, 100 Hz, trigger bmi160-dev0");

  constexpr int kScans = 300;  // more than one read's worth
  for (int k = 0; k < kScans; ++k) dev.pushScan(kT0 + k * kPeriod, rawAt(k), {11, 22, 33});
  std::size_t bad = 0;
  const auto samples = readSamples(gyro, kScans, &bad);
  ASSERT_EQ(samples.size(), static_cast<std::size_t>(kScans));
  EXPECT_EQ(bad, 0u);
  for (int k = 0; k < kScans; ++k) {
    const auto& s = samples[static_cast<std::size_t>(k)];
    EXPECT_DOUBLE_EQ(s.t, static_cast<double>(kT0 + k * kPeriod) * 1e-9);
    for (int a = 0; a < 3; ++a)
      EXPECT_DOUBLE_EQ(s.rate[a], static_cast<double>(rawAt(k)[static_cast<std::size_t>(a)]) * kBmi160Scale);
  }
  gyro.close();
  EXPECT_FALSE(dev.bufferEnabled()) << "the buffer it enabled is disabled again";
  EXPECT_EQ(dev.attribute("current_timestamp_clock"), "monotonic") << "nothing else restored";
  EXPECT_EQ(dev.openFdCount(), 0);
  EXPECT_EQ(dev.violations(), std::vector<std::string>{});
}

TEST(IioGyro, KeepsWhateverChannelsTheDeviceKeepsAndAPerAxisScale) {
  // A big-endian 12-bit gyro with per-axis scales and an offset, the timestamp first.
  FakeIioDevice::Config c;
  c.name = "fakegyro";
  c.needs_trigger = false;
  c.sampling_attribute = "sampling_frequency";
  c.channels = {{"in_timestamp", 0, "le:s64/64>>0", true},
                {"in_anglvel_x", 1, "be:s12/16>>4", false},
                {"in_anglvel_y", 2, "be:s12/16>>4", false},
                {"in_anglvel_z", 3, "be:s12/16>>4", false},
                {"in_temp", 4, "le:u8/8>>0", true}};
  c.attributes = {{"in_anglvel_x_scale", "0.001"}, {"in_anglvel_y_scale", "0.002"},
                  {"in_anglvel_z_scale", "0.004"}, {"in_anglvel_offset", "-10"}};
  FakeIioDevice dev(c);
  IioGyroOptions o = optionsFor(c, "iio:device0");
  o.sampling_hz = 200;
  IioGyro gyro(o, dev);
  ASSERT_TRUE(gyro.open().has_value());
  EXPECT_EQ(dev.attribute("sampling_frequency"), "200");
  EXPECT_EQ(dev.attribute("scan_elements/in_temp_en"), "0");
  EXPECT_EQ(dev.scanBytes(), 16u);  // timestamp 8, three 16-bit words, padded to 8
  dev.pushScan(kT0, {100, -100, 2047 - 1});
  const auto s = readSamples(gyro, 1);
  ASSERT_EQ(s.size(), 1u);
  EXPECT_DOUBLE_EQ(s[0].rate.x(), (100 - 10) * 0.001);
  EXPECT_DOUBLE_EQ(s[0].rate.y(), (-100 - 10) * 0.002);
  EXPECT_DOUBLE_EQ(s[0].rate.z(), (2046 - 10) * 0.004);
  EXPECT_THAT(gyro.describe(), HasSubstr("200 Hz"));
  gyro.close();
  EXPECT_EQ(dev.violations(), std::vector<std::string>{});
}

TEST(IioGyro, AChannelTheDriverKeepsEnabledIsReadAlongWithAWarning) {
  FakeIioDevice::Config c;
  c.locked_channels = {"in_accel_y"};
  FakeIioDevice dev(c);
  IioGyro gyro(optionsFor(c), dev);
  ASSERT_TRUE(gyro.open().has_value());
  ASSERT_EQ(gyro.warnings().size(), 1u);
  EXPECT_THAT(gyro.warnings()[0], HasSubstr("cannot disable scan_elements/in_accel_y_en"));
  EXPECT_EQ(dev.scanBytes(), 16u);  // x, y, z, accel y at 6, the timestamp at 8
  dev.pushScan(kT0, rawAt(0), {1, -32768, 3});  // the accel at its rail: not the gyro's business
  const auto s = readSamples(gyro, 1);
  ASSERT_EQ(s.size(), 1u);
  EXPECT_DOUBLE_EQ(s[0].rate.z(), static_cast<double>(rawAt(0)[2]) * kBmi160Scale);
  gyro.close();
  EXPECT_EQ(dev.violations(), std::vector<std::string>{});
}

TEST(IioGyro, ARateTheDeviceDoesNotOfferIsRefusedWithTheOnesItDoes) {
  FakeIioDevice dev;
  IioGyroOptions o = optionsFor(FakeIioDevice::Config{});
  o.sampling_hz = 333;
  IioGyro gyro(o, dev);
  const auto r = gyro.open();
  ASSERT_FALSE(r.has_value());
  EXPECT_THAT(std::string(r.error().c_str()),
              HasSubstr("iio:device0 (bmi160): in_anglvel_sampling_frequency 333 Hz refused"));
  EXPECT_THAT(std::string(r.error().c_str()), HasSubstr("25 50 100 200 400 800 1600 3200"));
  EXPECT_EQ(dev.openFdCount(), 0);
  EXPECT_FALSE(dev.bufferEnabled());
}

TEST(IioGyro, AnUnplugIsReportedAndTheDeviceIsFoundByNameAtItsNewIndex) {
  FakeIioDevice dev;
  IioGyro gyro(optionsFor(FakeIioDevice::Config{}), dev);
  ASSERT_TRUE(gyro.open().has_value());
  for (int k = 0; k < 20; ++k) dev.pushScan(kT0 + k * kPeriod, rawAt(k));
  EXPECT_EQ(readSamples(gyro, 20).size(), 20u);
  dev.unplug();
  std::vector<GyroSample> out(8);
  const auto lost = gyro.read(out, 5);
  ASSERT_FALSE(lost.has_value());
  EXPECT_EQ(lost.error().code(), ErrorCode::kDisconnected);
  EXPECT_THAT(std::string(lost.error().c_str()), HasSubstr("iio:device0 (bmi160): the device went away"));
  gyro.close();
  EXPECT_EQ(dev.openFdCount(), 0);
  const auto gone = gyro.open();
  ASSERT_FALSE(gone.has_value());
  EXPECT_EQ(gone.error().code(), ErrorCode::kNotFound);
  EXPECT_THAT(std::string(gone.error().c_str()), HasSubstr("iio device \"bmi160\": no device of that name"));
  dev.replug(3);
  ASSERT_TRUE(gyro.open().has_value());
  EXPECT_EQ(gyro.label(), "iio:device3 (bmi160)");
  EXPECT_EQ(dev.attribute("trigger/current_trigger"), "bmi160-dev3");
  for (int k = 20; k < 40; ++k) dev.pushScan(kT0 + k * kPeriod, rawAt(k));
  const auto resumed = readSamples(gyro, 20);
  ASSERT_EQ(resumed.size(), 20u);
  EXPECT_DOUBLE_EQ(resumed[0].t, static_cast<double>(kT0 + 20 * kPeriod) * 1e-9);
  gyro.close();
  EXPECT_FALSE(dev.bufferEnabled());
  EXPECT_EQ(dev.openFdCount(), 0);
  EXPECT_EQ(dev.violations(), std::vector<std::string>{});
}

TEST(IioGyro, BadScansAreCountedAndSkipped) {
  FakeIioDevice dev;
  IioGyro gyro(optionsFor(FakeIioDevice::Config{}), dev);
  ASSERT_TRUE(gyro.open().has_value());
  dev.pushScan(kT0, rawAt(0));
  dev.pushScan(0, rawAt(1));                          // no timestamp
  dev.pushScan(kT0 - kPeriod, rawAt(2));              // backwards
  dev.pushScan(kT0, rawAt(3));                        // the same time again
  dev.pushScan(kT0 + kPeriod, {32767, 0, 0});         // x at the rail
  dev.pushScan(kT0 + 2 * kPeriod, {0, -32768, 0});    // y at the rail
  dev.pushScan(kT0 + 3 * kPeriod, rawAt(4));
  std::size_t bad = 0;
  const auto s = readSamples(gyro, 2, &bad);
  ASSERT_EQ(s.size(), 2u);
  EXPECT_EQ(bad, 5u);
  EXPECT_DOUBLE_EQ(s[1].t, static_cast<double>(kT0 + 3 * kPeriod) * 1e-9);
  // A broken driver's partial read: the part is counted, the whole scans before it kept.
  dev.pushScan(kT0 + 4 * kPeriod, rawAt(5));
  dev.pushScan(kT0 + 5 * kPeriod, rawAt(6));
  dev.shortReadNext(16 + 7);
  std::vector<GyroSample> out(8);
  const auto r = gyro.read(out, 5);
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ(r->samples, 1u);
  EXPECT_EQ(r->bad, 1u);
  EXPECT_EQ(r->last_bad, ScanVerdict::kTruncated);
  gyro.close();
  EXPECT_EQ(dev.violations(), std::vector<std::string>{});
}

std::string openError(FakeIioDevice& dev, const std::string& device = "bmi160") {
  IioGyro gyro(optionsFor(FakeIioDevice::Config{}, device), dev);
  const auto r = gyro.open();
  EXPECT_FALSE(r.has_value()) << device;
  EXPECT_EQ(dev.openFdCount(), 0) << "nothing left open after a failed open()";
  EXPECT_FALSE(dev.bufferEnabled());
  return r ? std::string() : std::string(r.error().c_str());
}

TEST(IioGyro, EveryStartUpRefusalNamesTheDevice) {
  {
    FakeIioDevice dev;
    EXPECT_THAT(openError(dev, "lsm6dsx"),
                HasSubstr("iio device \"lsm6dsx\": no device of that name under /fake/sys"));
    EXPECT_THAT(openError(dev, "iio:device7"), HasSubstr("iio device iio:device7: not under"));
  }
  {
    FakeIioDevice::Config c;
    c.name = "ads1015";
    c.channels = {{"in_voltage0", 0, "be:s12/16>>4", true}, {"in_timestamp", 4, "le:s64/64>>0", true}};
    FakeIioDevice dev(c);
    EXPECT_THAT(openError(dev, "ads1015"), HasSubstr("iio:device0 (ads1015) has no gyro channels"));
  }
  {
    FakeIioDevice dev;
    dev.setOtherReader(true);
    EXPECT_THAT(openError(dev), HasSubstr("iio:device0 (bmi160): /fake/dev/iio:device0 is in use by another reader"));
  }
  {
    FakeIioDevice dev;
    dev.setKernelConsumer(true);
    EXPECT_THAT(openError(dev), HasSubstr("iio:device0 (bmi160): buffer/enable: busy"));
  }
  {
    FakeIioDevice::Config c;
    c.settable_clocks = {"realtime"};
    FakeIioDevice dev(c);
    EXPECT_THAT(openError(dev), HasSubstr("cannot set current_timestamp_clock to monotonic "
                                          "(Invalid argument): it stamps on realtime"));
  }
  {
    FakeIioDevice::Config c;
    c.clock.clear();
    FakeIioDevice dev(c);
    EXPECT_THAT(openError(dev), HasSubstr("iio:device0 (bmi160): no current_timestamp_clock"));
  }
  {
    FakeIioDevice::Config c;
    c.attributes.erase("in_anglvel_scale");
    FakeIioDevice dev(c);
    EXPECT_THAT(openError(dev), HasSubstr("neither in_anglvel_x_scale nor in_anglvel_scale"));
  }
}

TEST(IioGyro, ABufferLeftEnabledByAReaderThatIsGoneIsTakenOverWithAWarning) {
  FakeIioDevice dev;
  dev.leaveBufferEnabled();
  IioGyro gyro(optionsFor(FakeIioDevice::Config{}), dev);
  const auto r = gyro.open();
  ASSERT_TRUE(r.has_value()) << r.error().c_str();
  ASSERT_EQ(gyro.warnings().size(), 1u);
  EXPECT_THAT(gyro.warnings()[0], HasSubstr("iio:device0 (bmi160): its buffer was left enabled"));
  EXPECT_EQ(dev.scanBytes(), 16u) << "re-enabled with the gyro's scan";
  gyro.close();
  EXPECT_EQ(dev.violations(), std::vector<std::string>{});
}

TEST(IioGyro, OptionsNameTheBadField) {
  IioGyroOptions o;
  o.device = "/dev/iio:device0";
  o.sampling_hz = -1;
  o.buffer_length = 1;
  const auto p = o.validate();
  ASSERT_EQ(p.size(), 3u);
  EXPECT_THAT(p[0], HasSubstr("device: \"/dev/iio:device0\" is a path"));
  EXPECT_THAT(p[1], HasSubstr("sampling_hz"));
  EXPECT_THAT(p[2], HasSubstr("buffer_length"));
  EXPECT_THAT(IioGyroOptions{}.validate().at(0), HasSubstr("device: needed"));
  IioGyroOptions long_path;
  long_path.device = "/" + std::string(5000, 'a');
  EXPECT_THAT(long_path.validate().at(0), HasSubstr("... (5001 bytes)\" is a path"));
  EXPECT_LT(long_path.validate().at(0).size(), 200u);
}

TEST(IioGyro, OptionsThatAreNotValidAreRefusedBeforeTheDeviceIsTouched) {
  FakeIioDevice dev;
  IioGyroOptions o = optionsFor(FakeIioDevice::Config{});
  o.sampling_hz = -1;
  o.buffer_length = 1;
  IioGyro gyro(o, dev);
  const auto r = gyro.open();
  ASSERT_FALSE(r.has_value());
  EXPECT_EQ(r.error().code(), ErrorCode::kInvalidArgument);
  EXPECT_THAT(std::string(r.error().c_str()), HasSubstr("sampling_hz: -1 is outside"));
  EXPECT_THAT(std::string(r.error().c_str()), HasSubstr("; buffer_length: 1 is outside"));
  EXPECT_EQ(dev.openFdCount(), 0);
  EXPECT_FALSE(dev.bufferEnabled());
}

TEST(IioGyro, TheKernelsSeamFindsADeviceByNameInARealDirectoryTree) {
  // sysfs as plain files in a temporary directory; no character device: open() finds the
  // device by its name through SystemIioIo and then reports the missing node.
  const char* base = std::getenv("TMPDIR");
  std::string pattern = std::string(base && *base ? base : "/tmp") + "/omnipose-iio-XXXXXX";
  ASSERT_NE(mkdtemp(pattern.data()), nullptr);
  const std::filesystem::path root(pattern);
  std::filesystem::create_directories(root / "sys" / "iio:device2");
  std::filesystem::create_directories(root / "sys" / "iio:device0");
  std::filesystem::create_directories(root / "dev");
  std::ofstream(root / "sys" / "iio:device2" / "name") << "bmi160\n";
  std::ofstream(root / "sys" / "iio:device0" / "name") << "ads1015\n";
  IioGyroOptions o;
  o.device = "bmi160";
  o.sysfs_root = (root / "sys").string();
  o.dev_root = (root / "dev").string();
  IioGyro gyro(o);
  const auto r = gyro.open();
  ASSERT_FALSE(r.has_value());
  EXPECT_EQ(r.error().code(), ErrorCode::kNotFound);
  EXPECT_THAT(std::string(r.error().c_str()), HasSubstr("iio:device2 (bmi160): cannot open " + o.dev_root +
                                                        "/iio:device2"));
  std::filesystem::remove_all(root);
}

}  // namespace
}  // namespace omnipose
