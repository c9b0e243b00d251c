// The refinement pass's check for content moving on its own (src/pipeline/moving_content.hpp,
// private): a textured panorama moved by a known shift, with and without a "person" that
// moves differently, against windows that report the background's shift.

#include "pipeline/moving_content.hpp"

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <vector>

#include "omnipose/calibration.hpp"

namespace omnipose {
namespace {

using pipeline::MovingContentCheck;

constexpr int kWindow = 110, kStep = 20;
constexpr int kBackgroundShift = 3;  ///< current(u) = reference(u + 3): du = +3
constexpr int kPersonShift = 5;      ///< people: current(u) = reference(u - 5), du = -5

class MovingContentTest : public ::testing::Test {
 protected:
  MovingContentTest()
      : geometry_(Calibration{}.panorama),
        width_(geometry_.width),
        height_(geometry_.height),
        warp_(geometry_),
        pool_(1) {
    // The de-rotation of the identity: the current panorama is its own source.
    warp_.projectGridRows(Eigen::Matrix3d::Identity(), 0, warp_.gridRows());
    for (int k = 0; k * kStep + kWindow <= width_; ++k)
      centers_.push_back(k * kStep + 0.5 * (kWindow - 1));
  }

  /// Texture of grey levels around 128 with detail at a few pixels' scale.
  cv::Mat texture(int width, int seed) const {
    cv::Mat t(height_, width, CV_32FC1);
    cv::RNG rng(static_cast<std::uint64_t>(seed));
    rng.fill(t, cv::RNG::UNIFORM, 0.0, 255.0);
    cv::GaussianBlur(t, t, cv::Size(0, 0), 1.5);
    return (t - 128.0f) * 3.0f + 128.0f;
  }

  /// `image` shifted so that out(u) = image(u + shift), columns wrapping.
  static cv::Mat shifted(const cv::Mat& image, int shift) {
    cv::Mat out(image.size(), image.type());
    for (int u = 0; u < image.cols; ++u)
      image.col(((u + shift) % image.cols + image.cols) % image.cols).copyTo(out.col(u));
    return out;
  }

  std::vector<WindowMotion> backgroundWindows() const {
    std::vector<WindowMotion> windows(centers_.size());
    for (std::size_t k = 0; k < windows.size(); ++k) {
      windows[k].center_u = centers_[k];
      windows[k].du = kBackgroundShift;
      windows[k].valid = true;
      windows[k].confidence = 0.9;
    }
    return windows;
  }

  std::vector<double> measure(const cv::Mat& reference, const cv::Mat& current,
                              const std::vector<WindowMotion>& windows,
                              const std::vector<Eigen::Vector2d>& expected = {}) {
    MovingContentCheck check(cv::Mat::ones(height_, width_, CV_32FC1), kWindow, 0, centers_);
    std::vector<double> fraction(windows.size(), -1.0);
    check.measure(reference, current, warp_, windows, pool_, fraction, expected);
    return fraction;
  }

  /// Whether window k's columns overlap [first, last).
  bool overlaps(std::size_t k, int first, int last) const {
    const double lo = centers_[k] - 0.5 * (kWindow - 1), hi = lo + kWindow;
    return hi > first && lo < last;
  }

  /// The share of window k's taper weight (along u) on columns [first, last).
  double coverage(std::size_t k, int first, int last) const {
    const int lo = static_cast<int>(std::lround(centers_[k] - 0.5 * (kWindow - 1)));
    double inside = 0.0, all = 0.0;
    for (int j = 0; j < kWindow; ++j) {
      all += windowTaper(j, kWindow);
      if (lo + j >= first && lo + j < last) inside += windowTaper(j, kWindow);
    }
    return inside / all;
  }

  /// A textured background moved by kBackgroundShift, with people (a darker texture of
  /// `width` columns at [first, first + width) of the reference) moved kPersonShift columns
  /// the other way in the current panorama. Textures drawn with seeds `seed` and seed + 1.
  struct People {
    cv::Mat reference, current;
    int first, width;
    int last() const { return first + width; }
  };
  People people(int first, int width, int seed) const {
    const cv::Mat background = texture(width_, seed);
    const cv::Mat person = texture(width, seed + 1) * 0.5f + 20.0f;
    People scene{background.clone(), shifted(background, kBackgroundShift), first, width};
    person.copyTo(scene.reference.colRange(first, first + width));
    person.copyTo(scene.current.colRange(first + kPersonShift, first + kPersonShift + width));
    return scene;
  }

  /// Windows first..last (centred on the people) locked onto them: their shift is the
  /// people's, du = -kPersonShift.
  void lockOnto(std::vector<WindowMotion>& windows, std::size_t first, std::size_t last,
                const People& scene) const {
    for (std::size_t k = first; k <= last; ++k) {
      ASSERT_GT(centers_[k], scene.first);
      ASSERT_LT(centers_[k], scene.last() + kPersonShift);
      windows[k].du = -kPersonShift;
    }
  }

  /// Windows clear of the people (and 10 columns around them) disagree nowhere; windows they
  /// cover at least a tenth of (in the current panorama) disagree at least `share` times
  /// that cover: most of the people, and the background they uncover, disagrees.
  void expectFound(const std::vector<double>& fraction, const People& scene,
                   double share) const {
    const int first = scene.first + kPersonShift, last = scene.last() + kPersonShift;
    for (std::size_t k = 0; k < fraction.size(); ++k) {
      const double cover = coverage(k, first, last);
      if (!overlaps(k, first - 15, last + 10)) {
        EXPECT_LE(fraction[k], MovingContentCheck::kKeepFraction) << "window " << k;
      } else if (cover >= 0.1) {
        EXPECT_GE(fraction[k], share * cover) << "window " << k << ", people covering " << cover;
      }
    }
  }

  PanoramaGeometry geometry_;
  int width_, height_;
  PanoramaWarp warp_;
  runtime::WorkerPool pool_;
  std::vector<double> centers_;
};

TEST_F(MovingContentTest, StaticSceneWithNoiseAndAnExposureStepDisagreesNowhere) {
  const cv::Mat reference = texture(width_, 1);
  cv::Mat current = shifted(reference, kBackgroundShift) * 1.3f + 12.0f;  // gain and offset
  cv::Mat noise(current.size(), CV_32FC1);
  cv::RNG(2).fill(noise, cv::RNG::NORMAL, 0.0, 3.0);
  current += noise;
  const auto fraction = measure(reference, current, backgroundWindows());
  for (std::size_t k = 0; k < fraction.size(); ++k) {
    EXPECT_LE(fraction[k], MovingContentCheck::kKeepFraction) << "window " << k;
    EXPECT_GE(fraction[k], 0.0) << "window " << k;
  }
}

TEST_F(MovingContentTest, APersonMovingOnItsOwnIsFoundInTheWindowsItCovers) {
  // A person 80 columns wide at [490, 570) of the reference moves 5 columns right while the
  // background moves 3 left: content at current u is at reference u - 5 (du = -5).
  const People scene = people(490, 80, 3);
  std::vector<WindowMotion> windows = backgroundWindows();
  // The three windows centred on the person locked onto it: their shift is the person's.
  // They must not lend that motion to the columns between them and their neighbours (which
  // would then see the person as background), and are found themselves (their background
  // does not move so).
  lockOnto(windows, 23, 25, scene);
  ASSERT_GT(centers_[23], scene.first + kPersonShift);  // within the person in both frames
  const auto fraction = measure(scene.reference, scene.current, windows);
  expectFound(fraction, scene, 0.5);
  for (std::size_t k = 0; k < fraction.size(); ++k) {
    if (coverage(k, scene.first + kPersonShift, scene.last() + kPersonShift) >= 0.1) {
      EXPECT_GE(fraction[k], MovingContentCheck::kDropFraction) << "window " << k;
    }
  }
}

TEST_F(MovingContentTest, PeopleSideBySideAreFoundWithTheFitsPrediction) {
  // Two people side by side, 140 columns at [470, 610) of the reference, move 5 columns
  // right; the seven windows centred on them locked onto them, the majority of each one's
  // nine neighbours: their median is the people's motion. The fit's prediction (the
  // background's shift everywhere) still tells them apart.
  const People scene = people(470, 140, 7);
  std::vector<WindowMotion> windows = backgroundWindows();
  lockOnto(windows, 21, 27, scene);
  const std::vector<Eigen::Vector2d> expected(windows.size(),
                                              Eigen::Vector2d(kBackgroundShift, 0.0));
  expectFound(measure(scene.reference, scene.current, windows, expected), scene, 0.4);
}

TEST_F(MovingContentTest, TooFewMeasuredWindowsCheckNothing) {
  const cv::Mat reference = texture(width_, 5);
  const cv::Mat current = texture(width_, 6);  // unrelated: everything disagrees
  std::vector<WindowMotion> windows = backgroundWindows();
  for (std::size_t k = MovingContentCheck::kMinWindows - 1; k < windows.size(); ++k)
    windows[k].valid = false;
  for (double f : measure(reference, current, windows)) EXPECT_EQ(f, 0.0);
}

TEST(MovingContentWeight, WholeUpToKeepNoneFromDropLinearBetween) {
  EXPECT_EQ(MovingContentCheck::weight(0.0), 1.0);
  EXPECT_EQ(MovingContentCheck::weight(MovingContentCheck::kKeepFraction), 1.0);
  EXPECT_EQ(MovingContentCheck::weight(MovingContentCheck::kDropFraction), 0.0);
  EXPECT_EQ(MovingContentCheck::weight(1.0), 0.0);
  const double middle =
      0.5 * (MovingContentCheck::kKeepFraction + MovingContentCheck::kDropFraction);
  EXPECT_NEAR(MovingContentCheck::weight(middle), 0.5, 1e-12);
}

TEST(MovingContentCheckConstruction, WindowsThatDoNotFitTheRowsAreRefused) {
  EXPECT_THROW(MovingContentCheck(cv::Mat::ones(50, 400, CV_32FC1), 110, 0, {54.5}),
               std::invalid_argument);
  EXPECT_THROW(MovingContentCheck(cv::Mat::ones(110, 400, CV_32FC1), 110, 0, {}),
               std::invalid_argument);
  EXPECT_THROW(MovingContentCheck(cv::Mat::ones(110, 400, CV_8UC1), 110, 0, {54.5}),
               std::invalid_argument);
}

}  // namespace
}  // namespace omnipose
