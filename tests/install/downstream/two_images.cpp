// The motion between two images: two_images CALIBRATION.yaml FIRST SECOND (README, Library).
#include <cstdio>
#include <omnipose/odometry.hpp>
#include <opencv2/imgcodecs.hpp>

int main(int argc, char** argv) {
  if (argc != 4) return 2;
  omnipose::Odometry odometry(omnipose::Calibration::load(argv[1]), {});
  (void)odometry.process(cv::imread(argv[2], cv::IMREAD_GRAYSCALE), {0.0});
  const auto step = odometry.process(cv::imread(argv[3], cv::IMREAD_GRAYSCALE), {1.0});
  if (!step || !step->tracked()) return 1;
  const Eigen::Vector3d w = step->relative.estimate.omega;
  std::printf("rotation vector %.5f %.5f %.5f rad\n", w.x(), w.y(), w.z());
}
