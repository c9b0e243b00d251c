// libcamera source: its pure parts (format choice, camera choice, option checks) and its
// behaviour with no camera present. Its timestamp conversion (CLOCK_BOOTTIME -> wall clock)
// is common code, tested in driver_common_test.cpp.

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <filesystem>

#include "libcamera/libcamera_formats.hpp"
#include "libcamera/libcamera_source.hpp"

using ::testing::HasSubstr;

namespace omnipose {
namespace {

using namespace std::chrono_literals;
using libcam::fourcc;

constexpr std::uint32_t kR8 = fourcc('R', '8', ' ', ' ');
constexpr std::uint32_t kNV12 = fourcc('N', 'V', '1', '2');
constexpr std::uint32_t kYUV420 = fourcc('Y', 'U', '1', '2');
constexpr std::uint32_t kYUYV = fourcc('Y', 'U', 'Y', 'V');
constexpr std::uint32_t kUYVY = fourcc('U', 'Y', 'V', 'Y');
constexpr std::uint32_t kMJPEG = fourcc('M', 'J', 'P', 'G');
constexpr std::uint32_t kXRGB = fourcc('X', 'R', '2', '4');
constexpr std::uint32_t kRaw10 = fourcc('p', 'R', 'A', 'A');

LibcameraOptions libcameraConfig(const char* camera = "0", const char* format = "YUYV") {
  LibcameraOptions c;
  c.camera = camera;
  c.width = 640;
  c.height = 480;
  c.fps = 30;
  c.format = format;
  return c;
}

// ---- format choice ----------------------------------------------------------------------

TEST(LibcameraFormatTest, ConvertibleFormatsAndTheirConversion) {
  ASSERT_NE(libcam::findGreyFormat(kR8), nullptr);
  EXPECT_EQ(libcam::findGreyFormat(kR8)->conversion, libcam::GreyConversion::kLumaPlane);
  EXPECT_EQ(libcam::findGreyFormat(kNV12)->conversion, libcam::GreyConversion::kLumaPlane);
  EXPECT_EQ(libcam::findGreyFormat(kYUYV)->conversion, libcam::GreyConversion::kPackedLuma0);
  EXPECT_EQ(libcam::findGreyFormat(kUYVY)->conversion, libcam::GreyConversion::kPackedLuma1);
  EXPECT_EQ(libcam::findGreyFormat(kMJPEG)->conversion, libcam::GreyConversion::kJpeg);
  EXPECT_EQ(libcam::findGreyFormat(kXRGB), nullptr);
  EXPECT_EQ(libcam::findGreyFormat(kRaw10), nullptr);
  EXPECT_EQ(libcam::greyFormats().front().fourcc, kR8) << "no conversion is best";
  EXPECT_EQ(libcam::greyFormats().back().fourcc, kMJPEG) << "decoding is last";
}

TEST(LibcameraFormatTest, ParsesLibcameraAndV4l2Names) {
  EXPECT_EQ(libcam::parseFormatName("GREY"), kR8);
  EXPECT_EQ(libcam::parseFormatName("r8"), kR8);
  EXPECT_EQ(libcam::parseFormatName("Y8"), kR8);
  EXPECT_EQ(libcam::parseFormatName("nv12"), kNV12);
  EXPECT_EQ(libcam::parseFormatName("YUV420"), kYUV420);
  EXPECT_EQ(libcam::parseFormatName("MJPG"), kMJPEG);
  EXPECT_EQ(libcam::parseFormatName("MJPEG"), kMJPEG);
  EXPECT_EQ(libcam::parseFormatName("auto"), 0u);
  EXPECT_EQ(libcam::parseFormatName(""), 0u);
  EXPECT_FALSE(libcam::parseFormatName("XRGB8888"));
  EXPECT_EQ(libcam::formatName(kNV12), "NV12");
  EXPECT_EQ(libcam::formatName(kXRGB), "XR24");
}

TEST(LibcameraFormatTest, RequestedFormatWhenOffered) {
  const std::vector<std::uint32_t> offered = {kXRGB, kNV12, kYUYV, kMJPEG};
  auto c = libcam::chooseFormat("YUYV", offered);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->fourcc, kYUYV);
  EXPECT_FALSE(c->substituted);
  c = libcam::chooseFormat("mjpg", offered);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->fourcc, kMJPEG);
}

TEST(LibcameraFormatTest, BestOfferedWhenAutoOrNotOffered) {
  // A Raspberry Pi ISP: no R8, but YUV420 and NV12 (a luma plane to copy) before packed.
  const std::vector<std::uint32_t> pi = {kXRGB, kYUYV, kYUV420, kNV12, kRaw10};
  auto c = libcam::chooseFormat("auto", pi);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->fourcc, kNV12);
  EXPECT_FALSE(c->substituted);
  // A UVC camera through libcamera: YUYV and MJPEG; GREY asked, YUYV substituted.
  const std::vector<std::uint32_t> uvc = {kMJPEG, kYUYV};
  c = libcam::chooseFormat("GREY", uvc);
  ASSERT_TRUE(c);
  EXPECT_EQ(c->fourcc, kYUYV);
  EXPECT_TRUE(c->substituted);
  c = libcam::chooseFormat("", std::vector<std::uint32_t>{kMJPEG});
  ASSERT_TRUE(c);
  EXPECT_EQ(c->fourcc, kMJPEG);
}

TEST(LibcameraFormatTest, NothingConvertibleOrUnknownNameAreErrors) {
  auto c = libcam::chooseFormat("YUYV", std::vector<std::uint32_t>{kXRGB, kRaw10});
  ASSERT_FALSE(c);
  EXPECT_EQ(c.error().code(), ErrorCode::kUnsupportedFormat);
  EXPECT_THAT(c.error().message(), HasSubstr("offers: XR24 pRAA"));
  c = libcam::chooseFormat("RGB565", std::vector<std::uint32_t>{kNV12});
  ASSERT_FALSE(c);
  EXPECT_EQ(c.error().code(), ErrorCode::kInvalidArgument);
  EXPECT_THAT(c.error().message(), HasSubstr("RGB565"));
}

// ---- camera choice ----------------------------------------------------------------------

TEST(LibcameraCameraTest, IndexOrId) {
  const std::vector<std::string> ids = {"/base/soc/i2c0mux/i2c@1/imx219@10",
                                        "\\_SB_.PCI0.XHC_.RHUB.HS05-5:1.0-0c45:6366"};
  auto s = libcam::parseCameraSelector("1");
  ASSERT_TRUE(s.index);
  EXPECT_EQ(*s.index, 1u);
  auto i = libcam::selectCamera(s, ids);
  ASSERT_TRUE(i);
  EXPECT_EQ(*i, 1u);
  s = libcam::parseCameraSelector("/base/soc/i2c0mux/i2c@1/imx219@10");
  EXPECT_FALSE(s.index);
  i = libcam::selectCamera(s, ids);
  ASSERT_TRUE(i);
  EXPECT_EQ(*i, 0u);
}

TEST(LibcameraCameraTest, MissingCamerasAreClearErrors) {
  const std::vector<std::string> none;
  auto i = libcam::selectCamera(libcam::parseCameraSelector("0"), none);
  ASSERT_FALSE(i);
  EXPECT_EQ(i.error().code(), ErrorCode::kNoDevice);
  EXPECT_EQ(i.error().message().substr(0, 10), "no camera:");

  const std::vector<std::string> one = {"/base/soc/i2c0mux/i2c@1/imx219@10"};
  i = libcam::selectCamera(libcam::parseCameraSelector("2"), one);
  ASSERT_FALSE(i);
  EXPECT_EQ(i.error().code(), ErrorCode::kNoDevice);
  EXPECT_THAT(i.error().message(), HasSubstr("0: /base/soc/i2c0mux/i2c@1/imx219@10"));
  i = libcam::selectCamera(libcam::parseCameraSelector("imx477"), one);
  ASSERT_FALSE(i);
  EXPECT_EQ(i.error().code(), ErrorCode::kNotFound);
  EXPECT_THAT(i.error().message(), HasSubstr("'imx477'"));
}

// ---- configuration ----------------------------------------------------------------------

TEST(LibcameraConfigTest, Validation) {
  EXPECT_TRUE(validate(LibcameraOptions{}).empty()) << "the defaults are valid";
  EXPECT_TRUE(validate(libcameraConfig()).empty());
  EXPECT_TRUE(validate(libcameraConfig("0", "auto")).empty());
  EXPECT_TRUE(validate(libcameraConfig("0", "")).empty()) << "empty = auto";
  LibcameraOptions bad = libcameraConfig("", "XRGB8888");
  bad.width = 0;
  bad.height = -5;
  bad.fps = 0;
  bad.buffer_count = 0;
  bad.clock_resync = 0ms;
  bad.clock_samples = 0;
  const auto problems = validate(bad);
  ASSERT_EQ(problems.size(), 8u) << ::testing::PrintToString(problems);
  EXPECT_EQ(problems[0].rfind("source.camera: ", 0), 0u);
  EXPECT_EQ(problems[1], "source.width: must be in [1, 16384], is 0");
  EXPECT_EQ(problems[2], "source.height: must be in [1, 16384], is -5");
  EXPECT_EQ(problems[3], "source.fps: must be in (0, 1000]");
  EXPECT_EQ(problems[4].rfind("source.format: 'XRGB8888' cannot be turned into grey", 0), 0u)
      << problems[4];
  EXPECT_EQ(problems[5], "buffer_count: must be in [1, 32], is 0");
  EXPECT_EQ(problems[6], "clock_resync: must be >= 1 ms");
  EXPECT_EQ(problems[7], "clock_samples: must be in [1, 16], is 0");
  EXPECT_EQ(libcam::frameDurationUs(30.0), 33333);
  EXPECT_EQ(libcam::frameDurationUs(25.0), 40000);

  LibcameraOptions o;
  o.clock_samples = 17;
  EXPECT_EQ(validate(o), std::vector<std::string>{"clock_samples: must be in [1, 16], is 17"});
}

TEST(LibcameraConfigTest, InvalidConfigurationFailsBeforeTouchingLibcamera) {
  LibcameraSource source(libcameraConfig("0", "XRGB8888"));
  auto r = source.open();
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code(), ErrorCode::kInvalidArgument);
  EXPECT_THAT(r.error().message(), HasSubstr("libcamera camera 0: source.format: 'XRGB8888'"));
}

// ---- no camera here ---------------------------------------------------------------------

bool anyMediaDevice() {
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator("/dev", ec))
    if (e.path().filename().string().rfind("media", 0) == 0) return true;
  return false;
}

TEST(LibcameraSourceTest, NoCameraIsAClearError) {
  if (anyMediaDevice()) GTEST_SKIP() << "a media device exists here; this test needs none";
  LibcameraSource source(libcameraConfig("0", "auto"));
  EXPECT_THAT(source.describe(), HasSubstr("not open"));
  auto r = source.open();
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code(), ErrorCode::kNoDevice);
  EXPECT_THAT(r.error().message(), HasSubstr("no camera"));
  EXPECT_THAT(r.error().message(), HasSubstr("libcamera camera 0"));
  cv::Mat out(480, 640, CV_8UC1);
  auto n = source.next(out, 10ms);
  ASSERT_FALSE(n);
  EXPECT_EQ(n.error().code(), ErrorCode::kInvalidArgument) << "not open";
  source.close();
  source.close();

  // Twice, and two sources at once: the shared CameraManager allows it.
  LibcameraSource a(libcameraConfig("0")), b(libcameraConfig("some-id"));
  auto ra = a.open();
  auto rb = b.open();
  ASSERT_FALSE(ra);
  ASSERT_FALSE(rb);
  EXPECT_EQ(ra.error().code(), ErrorCode::kNoDevice);
  EXPECT_EQ(rb.error().code(), ErrorCode::kNoDevice);
}

TEST(LibcameraSourceTest, VersionIsTheOneBuiltAgainst) {
  EXPECT_FALSE(LibcameraSource::libcameraVersion().empty());
  EXPECT_EQ(LibcameraSource::libcameraVersion().rfind("0.", 0), 0u);
}

}  // namespace
}  // namespace omnipose
