// omniposed --check (issue 9): the calibration and what it names (lens model, mask) and the
// pipeline against it are validated without opening a camera; every problem is a non-zero
// exit naming the file and the field.
#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "daemon_test_support.hpp"
#include "omnipose/calibration.hpp"

namespace omnipose {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;
using testing::TempDir;

fs::path omniposed() { return testing::binaryDir() / "omniposed"; }

/// A dataset directory with only a calibration (the check reads no frames).
struct CheckCase {
  TempDir tmp{"check"};
  fs::path dataset() const { return tmp / "data"; }
  int run(const Calibration& c) {
    fs::create_directories(dataset() / "frames");
    c.save(dataset() / "calibration.yaml");
    testing::writeText(tmp / "daemon.yaml", testing::fileSourceConfig(dataset(), "memq://", false));
    return testing::runProcess({omniposed().string(), "--config", (tmp / "daemon.yaml").string(), "--check"},
                               tmp / "out", tmp / "err", 60s);
  }
  std::string err() const { return testing::readText(tmp / "err"); }
};

TEST(DaemonCheck, AnOcamCalibLensWithAMaskPasses) {
  CheckCase t;
  Calibration c = Calibration::parse(
      "omni:\n  model: ocamcalib\n  ocamcalib_file: steep_mirror_800_ocamcalib.txt\n"
      "panorama: {width: 1100, height: 110}\n",
      "cal.yaml", fs::path(OMNIPOSE_SOURCE_DIR) / "tests/data/catadioptric");
  c.omni.mask = cv::Mat(800, 800, CV_8UC1, cv::Scalar(255));
  c.omni.mask_file = "mask.png";
  EXPECT_EQ(t.run(c), 0) << t.err();
  EXPECT_NE(t.err().find("lens model ocamcalib with a mask, panorama 1100x110: usable"),
            std::string::npos)
      << t.err();
}

TEST(DaemonCheck, AMaskOfTheWrongSizeFailsNamingTheFile) {
  CheckCase t;
  Calibration c;
  c.omni.mask = cv::Mat(720, 720, CV_8UC1, cv::Scalar(255));
  c.omni.mask_file = "mask.png";
  fs::create_directories(t.dataset());
  ASSERT_EQ(t.run(c), 0) << t.err();
  cv::imwrite((t.dataset() / "mask.png").string(), cv::Mat(10, 10, CV_8UC1, cv::Scalar(0)));
  EXPECT_EQ(testing::runProcess({omniposed().string(), "--config", (t.tmp / "daemon.yaml").string(), "--check"},
                                t.tmp / "out", t.tmp / "err", 60s),
            1);
  EXPECT_NE(t.err().find("omni.mask: mask.png is 10x10"), std::string::npos) << t.err();
}

TEST(DaemonCheck, APanoramaLowerThanTheWindowFails) {
  CheckCase t;
  Calibration c;
  c.panorama.height = 80;
  c.panorama.horizon_row = 39.5;
  EXPECT_EQ(t.run(c), 1);
  EXPECT_NE(t.err().find("window (110) must not exceed the panorama height (80)"), std::string::npos)
      << t.err();
}

}  // namespace
}  // namespace omnipose
