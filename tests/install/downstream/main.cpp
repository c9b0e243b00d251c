// Uses the core library, the renderer, a component and the generated LCM types of an
// installed omnipose: renders two frames 2 degrees of yaw apart and measures the turn; writes
// them with their calibration to the folder given as the first argument (for two_images).
#include <cmath>
#include <cstdio>
#include <numbers>
#include <omnipose/calibrate/lens_calibrator.hpp>
#include <omnipose/pipeline.hpp>
#include <omnipose/pose_t.hpp>
#include <omnipose/synth/synth.hpp>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

int main(int argc, char** argv) {
  const omnipose::Calibration calibration;  // the DESIGN.md example lens
  omnipose::synth::Scene scene;
  scene.texture.create(512, 1024, CV_32FC1);
  cv::randu(scene.texture, 0.0, 255.0);
  cv::GaussianBlur(scene.texture, scene.texture, cv::Size(0, 0), 3.0);
  const omnipose::synth::Renderer renderer(scene, calibration, {omnipose::synth::OutputKind::kOmni, 2});
  const double yaw = 2.0 * std::numbers::pi / 180.0;
  Eigen::Isometry3d turned = Eigen::Isometry3d::Identity();
  turned.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  cv::Mat first, second;
  renderer.render(Eigen::Isometry3d::Identity()).convertTo(first, CV_8UC1);
  renderer.render(turned).convertTo(second, CV_8UC1);
  if (argc > 1) {
    calibration.save(std::filesystem::path(argv[1]) / "calibration.yaml");
    cv::imwrite((std::filesystem::path(argv[1]) / "first.png").string(), first);
    cv::imwrite((std::filesystem::path(argv[1]) / "second.png").string(), second);
  }

  omnipose::Pipeline pipeline(calibration, omnipose::PipelineOptions{});
  const bool accepted = pipeline.process(first).has_value();
  const auto motion = pipeline.process(second);
  const double measured = motion ? std::abs(motion->estimate.omega.z()) : -1.0;
  const auto proposal = omnipose::calibrate::proposePanorama(120.0, 300.0, omnipose::OuterEdge::kTop);
  omnipose::pose_t pose;
  pose.sequence = 7;
  std::printf("downstream: first frame %s, |yaw| %.5f rad (rendered %.5f), proposed panorama "
              "%dx%d, pose_t encodes to %d bytes\n",
              accepted ? "accepted" : "rejected", measured, yaw, proposal.width, proposal.height,
              pose.getEncodedSize());
  return accepted && std::abs(measured - yaw) < 1e-3 && proposal.width > 0 ? 0 : 1;
}
