// Uses the core library, a component and the generated LCM types of an installed omnipose.
#include <cstdio>
#include <omnipose/calibrate/lens_calibrator.hpp>
#include <omnipose/pipeline.hpp>
#include <omnipose/pose_t.hpp>
#include <opencv2/core.hpp>

int main() {
  const omnipose::Calibration calibration;  // the DESIGN.md example lens
  omnipose::PipelineOptions options;
  options.refine_iterations = 0;
  omnipose::Pipeline pipeline(calibration, options);
  const cv::Mat frame(calibration.omni.image_height, calibration.omni.image_width, CV_8UC1,
                      cv::Scalar(128));
  const auto first = pipeline.process(frame);
  const auto proposal = omnipose::calibrate::proposePanorama(120.0, 300.0, omnipose::OuterEdge::kTop);
  omnipose::pose_t pose;
  pose.sequence = 7;
  std::printf("downstream: first frame %s, proposed panorama %dx%d, pose_t encodes to %d bytes\n",
              first ? "accepted" : "rejected", proposal.width, proposal.height,
              pose.getEncodedSize());
  return first && proposal.width > 0 ? 0 : 1;
}
