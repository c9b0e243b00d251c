// Places (src/map/place_memory.hpp): the signature does not change with the heading, tells
// two different views apart, and ignores brightness; the memory forgets the least recently
// used place first and allocates nothing once built.
#include <gtest/gtest.h>

#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "allocation_counter.hpp"
#include "map/place_memory.hpp"

namespace omnipose::map {
namespace {

const cv::Size kPanorama(1100, 110);

/// A band of the bundled indoor photo, `row0` rows down, as a CV_32FC1 panorama.
cv::Mat photoBand(int row0) {
  const cv::Mat photo =
      cv::imread((std::filesystem::path(OMNIPOSE_SOURCE_DIR) / "tests/data/equirect/indoor_1024x512.jpg").string(),
                 cv::IMREAD_GRAYSCALE);
  EXPECT_FALSE(photo.empty());
  cv::Mat band, out;
  cv::resize(photo.rowRange(row0, row0 + 110), band, kPanorama, 0, 0, cv::INTER_LINEAR);
  band.convertTo(out, CV_32F);
  return out;
}

/// `p` turned by `columns` columns (a yaw).
cv::Mat turned(const cv::Mat& p, int columns) {
  cv::Mat out(p.size(), p.type());
  for (int u = 0; u < p.cols; ++u) p.col(u).copyTo(out.col((u + columns) % p.cols));
  return out;
}

TEST(PlaceSignature, IsTheSameWhicheverWayTheRobotFaces) {
  PlaceSignature signer(kPanorama);
  const cv::Mat place = photoBand(200);
  PlaceSignature::Vector a, b, c;
  signer.compute(place, a);
  for (int columns : {1, 137, 550, 1003}) {
    signer.compute(turned(place, columns), b);
    EXPECT_GT(PlaceSignature::similarity(a, b), 0.9999) << columns << " columns";
  }
  signer.compute(place * 0.5 + 40.0, c);  // darker, less contrast
  EXPECT_GT(PlaceSignature::similarity(a, c), 0.9999);
}

TEST(PlaceSignature, TellsDifferentViewsApart) {
  PlaceSignature signer(kPanorama);
  PlaceSignature::Vector a, b, flat;
  signer.compute(photoBand(200), a);
  signer.compute(photoBand(330), b);
  const double different = PlaceSignature::similarity(a, b);
  ::testing::Test::RecordProperty("different_views_similarity", std::to_string(different));
  EXPECT_LT(different, 0.5);
  signer.compute(cv::Mat(kPanorama, CV_32FC1, cv::Scalar(90)), flat);
  EXPECT_EQ(PlaceSignature::similarity(a, flat), 0.0) << "no texture, no signature";
}

TEST(PlaceMemory, ForgetsTheLeastRecentlyUsedPlaceNumbersThemAndAllocatesNothing) {
  PlaceMemory memory(4, kPanorama);
  PlaceSignature signer(kPanorama);
  const cv::Mat view = photoBand(200);
  PlaceSignature::Vector signature;
  signer.compute(view, signature);
  testing::AllocationCounter counter;
  for (int id = 0; id < 4; ++id) memory.store(id, view, signature, 10 * id, id / 30.0, 0.0);
  memory.touch(1);
  memory.touch(0);
  EXPECT_EQ(memory.size(), 4);
  EXPECT_EQ(memory.leastRecentlyUsed(-1, -1), 2);
  EXPECT_EQ(memory.leastRecentlyUsed(2, -1), 3);
  memory.remove(2);
  EXPECT_EQ(memory.size(), 3);
  EXPECT_EQ(memory.leastRecentlyUsed(-1, -1), 3);
  memory.store(2, view, signature, 50, 50 / 30.0, 0.0);
  EXPECT_EQ(memory.stored(), 5) << "forgotten places count";
  EXPECT_EQ(memory[2].serial, 5) << "the newest";
  EXPECT_EQ(memory[3].serial, 4);
  memory.remove(2);
  if (testing::AllocationCounter::available()) {
    EXPECT_EQ(counter.stop(), 0);
  }
  EXPECT_EQ(memory[1].sequence, 10);
  EXPECT_EQ(memory[1].panorama.type(), CV_8UC1);
  EXPECT_NEAR(memory[1].panorama.at<unsigned char>(50, 500), view.at<float>(50, 500), 0.5);
}

}  // namespace
}  // namespace omnipose::map
