// The one image decoder (image_decode.hpp): headers are read before any pixel, declared sizes
// are bounded, and no file — bomb, truncated, garbage, FIFO, device — throws or is decoded
// beyond its bounds.
#include "omnipose/image_decode.hpp"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

#include "bad_images.hpp"
#include "omnipose/io/dataset.hpp"

using ::testing::HasSubstr;

namespace omnipose {
namespace {
namespace fs = std::filesystem;
using testing::Bytes;

cv::Mat testFrame() {
  cv::Mat frame(120, 160, CV_8UC1);
  cv::randu(frame, 0, 255);
  return frame;
}

std::span<const std::uint8_t> span(const Bytes& b) { return {b.data(), b.size()}; }

class ImageDecodeFiles : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("omnipose_image_decode_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST(ImageHeader, ReadsTheDeclaredSizeOfEveryAcceptedFormat) {
  const cv::Mat frame = testFrame();
  for (const auto& [ext, format] : {std::pair{".png", ImageFormat::kPng},
                                    std::pair{".jpg", ImageFormat::kJpeg},
                                    std::pair{".pgm", ImageFormat::kPnm},
                                    std::pair{".ppm", ImageFormat::kPnm},
                                    std::pair{".bmp", ImageFormat::kBmp}}) {
    SCOPED_TRACE(ext);
    cv::Mat image = frame;
    if (std::string(ext) == ".ppm") cv::cvtColor(frame, image, cv::COLOR_GRAY2BGR);
    const Bytes bytes = testing::encode(image, ext);
    const Expected<ImageHeader> header = readImageHeader(span(bytes), "x");
    ASSERT_TRUE(header) << header.error().c_str();
    EXPECT_EQ(header->format, format);
    EXPECT_EQ(header->width, 160);
    EXPECT_EQ(header->height, 120);
  }
  // A JPEG with EXIF and comment segments before the frame header, and a top-down BMP.
  const Bytes jpeg = testing::encode(frame, ".jpg");
  Bytes with_app = {0xFF, 0xD8, 0xFF, 0xE1, 0x00, 0x06, 'E', 'x', 'i', 'f', 0xFF, 0xFE, 0x00, 0x03, 'c'};
  with_app.insert(with_app.end(), jpeg.begin() + 2, jpeg.end());
  const Expected<ImageHeader> header = readImageHeader(span(with_app), "app.jpg");
  ASSERT_TRUE(header) << header.error().c_str();
  EXPECT_EQ(header->width, 160);
}

TEST(ImageDecode, BombsAreRefusedFromTheirHeaderWithoutDecoding) {
  struct Case {
    const char* name;
    Bytes bytes;
  };
  const Case cases[] = {{"header_only.png", testing::pngBomb(60000, 60000, false)},
                        {"bomb.png", testing::pngBomb(60000, 60000)},
                        {"bomb.jpg", testing::jpegBomb(60000, 60000)},
                        {"bomb32000.png", testing::pngBomb(32000, 32000)}};
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    EXPECT_LT(c.bytes.size(), 200u);
    cv::Mat out;
    ImageLimits frame_limits;
    frame_limits.exact_size = {720, 720};
    Expected<void> r = decodeImage(span(c.bytes), ImageColour::kAsStored, frame_limits, c.name, out);
    ASSERT_FALSE(r);
    EXPECT_EQ(r.error().code(), ErrorCode::kBadFrame);
    const std::string message(r.error().message());
    EXPECT_THAT(message, HasSubstr(c.name));
    EXPECT_THAT(message, HasSubstr("expected 720x720"));
    EXPECT_TRUE(out.empty());
    // Without an expected size the pixel bound refuses it just the same.
    r = decodeImage(span(c.bytes), ImageColour::kGrey, ImageLimits{}, c.name, out);
    ASSERT_FALSE(r);
    EXPECT_THAT(r.error().message(), HasSubstr("more than the 67108864 allowed"))
        << r.error().c_str();
  }
}

TEST(ImageDecode, ACompleteThirtyTwoThousandPixelPngCostsNoMemory) {
  const Bytes png = testing::zeroPng(32000, 32000);  // ~1 MB of file, 1 GB of pixels
  RecordProperty("png_bytes", static_cast<int>(png.size()));
  rusage before{};
  getrusage(RUSAGE_SELF, &before);
  cv::Mat out;
  ImageLimits limits;
  limits.exact_size = {720, 720};
  const Expected<void> r = decodeImage(span(png), ImageColour::kAsStored, limits, "zeros.png", out);
  rusage after{};
  getrusage(RUSAGE_SELF, &after);
  ASSERT_FALSE(r);
  EXPECT_THAT(r.error().message(), HasSubstr("32000x32000, expected 720x720"));
  EXPECT_LT(after.ru_maxrss - before.ru_maxrss, 64 * 1024) << "peak RSS grew by kB";
}

TEST(ImageDecode, TruncatedAndGarbageFilesOfEveryFormatAreBadFramesNeverExceptions) {
  const cv::Mat frame = testFrame();
  for (const auto& file : testing::badImageFiles(frame)) {
    SCOPED_TRACE(file.name);
    cv::Mat out;
    ImageLimits limits;
    limits.exact_size = frame.size();
    Expected<void> r;
    EXPECT_NO_THROW(r = decodeImage(span(file.bytes), ImageColour::kAsStored, limits,
                                    file.name.c_str(), out));
    if (file.must_reject) {
      ASSERT_FALSE(r);
      EXPECT_EQ(r.error().code(), ErrorCode::kBadFrame);
      EXPECT_THAT(r.error().message(), HasSubstr(file.name));
    } else if (r) {
      EXPECT_EQ(out.size(), frame.size());  // damaged pixels, but within bounds
    }
  }
}

TEST(ImageDecode, GoodFramesDecodeExactlyAndReuseTheOutputBuffer) {
  const cv::Mat frame = testFrame();
  for (const char* ext : {".png", ".pgm", ".bmp"}) {
    SCOPED_TRACE(ext);
    const Bytes bytes = testing::encode(frame, ext);
    cv::Mat out(frame.size(), CV_8UC1);
    const uchar* before = out.data;
    ImageLimits limits;
    limits.exact_size = frame.size();
    ASSERT_TRUE(decodeImage(span(bytes), ImageColour::kGrey, limits, "f", out));
    EXPECT_EQ(out.data, before);
    EXPECT_EQ(cv::norm(out, frame, cv::NORM_INF), 0.0);
  }
  const Bytes jpeg = testing::encode(frame, ".jpg");
  cv::Mat out;
  ASSERT_TRUE(decodeImage(span(jpeg), ImageColour::kBgr, ImageLimits{}, "f.jpg", out));
  EXPECT_EQ(out.type(), CV_8UC3);
  EXPECT_EQ(out.size(), frame.size());
}

TEST_F(ImageDecodeFiles, FilesThatAreNotRegularOrTooLargeAreRefusedWithoutReading) {
  const fs::path fifo = dir_ / "fifo.png";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  Expected<cv::Mat> r = readImage(fifo, ImageColour::kGrey);  // would block if it were read
  ASSERT_FALSE(r);
  EXPECT_THAT(r.error().message(), HasSubstr("fifo.png: not a regular file"));

  fs::create_symlink("/dev/zero", dir_ / "zero.png");
  r = readImage(dir_ / "zero.png", ImageColour::kGrey);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code(), ErrorCode::kBadFrame);

  r = readImage(dir_ / "missing.png", ImageColour::kGrey);
  ASSERT_FALSE(r);
  EXPECT_EQ(r.error().code(), ErrorCode::kNotFound);

  testing::writeBytes(dir_ / "big.png", Bytes(4096, 0));
  ImageLimits small;
  small.max_file_bytes = 1000;
  r = readImage(dir_ / "big.png", ImageColour::kGrey, small);
  ASSERT_FALSE(r);
  EXPECT_THAT(r.error().message(), HasSubstr("4096 bytes, more than the 1000 allowed"))
      << r.error().c_str();
}

TEST_F(ImageDecodeFiles, ReadFrameChecksTheCalibrationSizeBeforeDecoding) {
  const cv::Mat frame = testFrame();
  testing::writeBytes(dir_ / "f.png", testing::encode(frame, ".png"));
  Expected<cv::Mat> ok = readFrame(dir_ / "f.png", frame.size());
  ASSERT_TRUE(ok) << ok.error().c_str();
  EXPECT_EQ(cv::norm(*ok, frame, cv::NORM_INF), 0.0);
  Expected<cv::Mat> wrong = readFrame(dir_ / "f.png", {720, 720});
  ASSERT_FALSE(wrong);
  EXPECT_THAT(wrong.error().message(), HasSubstr("f.png: 160x120, expected 720x720"))
      << wrong.error().c_str();
  const cv::Mat deep(120, 160, CV_16UC1, cv::Scalar(1000));
  testing::writeBytes(dir_ / "deep.png", testing::encode(deep, ".png"));
  Expected<cv::Mat> sixteen = readFrame(dir_ / "deep.png", frame.size());
  ASSERT_FALSE(sixteen);
  EXPECT_THAT(sixteen.error().message(), HasSubstr("16-bit"));
}

}  // namespace
}  // namespace omnipose
