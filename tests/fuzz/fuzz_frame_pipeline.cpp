// Frame decode + pipeline on arbitrary bytes. The first byte chooses:
//   odd:  the rest is an image file, read with readFrame() (what the daemon's file source and
//         omnipose-replay use) and, when it decodes, handed to Pipeline::process as is
//         (any size, any channel count: process() must reject what it cannot use);
//   even: the rest is raw pixel data for two consecutive grey frames of the expected size
//         (repeated to fill), processed as a pair (arbitrary content: black, constant,
//         saturated, noise).
// process() must never throw or crash; its results must be finite.
#include <cmath>
#include <cstdint>
#include <opencv2/core.hpp>

#include "fuzz_support.hpp"
#include "omnipose/calibration.hpp"
#include "omnipose/io/dataset.hpp"
#include "omnipose/pipeline.hpp"

namespace {

// A small omni camera (128 x 128 image, 200 x 32 panorama, 32 x 32 windows) keeps each
// execution fast; the code paths are those of the full-size setting.
constexpr const char* kCalibration = R"(omni:
  image_width: 128
  image_height: 128
  center: [63.5, 63.5]
  radius_inner: 16.0
  radius_outer: 60.0
  azimuth_zero_deg: 0.0
  azimuth_direction: cw
  outer_edge: top
panorama:
  width: 200
  height: 32
  horizon_row: 15.5
  forward_column: 0.0
)";

omnipose::Pipeline& pipeline() {
  static omnipose::Pipeline p = [] {
    omnipose::PipelineOptions o;
    o.registration.window = 32;
    o.registration.step = 16;
    return omnipose::Pipeline(omnipose::Calibration::parse(kCalibration, "fuzz calibration"), o);
  }();
  return p;
}

void check(const omnipose::Expected<omnipose::FrameMotion>& r) {
  if (!r) return;
  const auto& e = r->estimate;
  if (!r->has_motion || e.status == omnipose::FitStatus::kLost) return;
  if (!e.omega.allFinite() || !e.tau.allFinite() || !r->rotation.allFinite() ||
      !std::isfinite(r->tau_norm))
    __builtin_trap();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  omnipose::Pipeline& p = pipeline();
  p.reset();
  const std::uint8_t mode = data[0];
  ++data;
  --size;
  if (mode & 1) {
    const auto path = omnipose::fuzz::scratch() / "frame.img";
    omnipose::fuzz::writeFile(path, data, size);
    const auto image = omnipose::readFrame(path);
    if (!image) return 0;
    check(p.process(*image));
    check(p.process(*image));
    return 0;
  }
  cv::Mat a(128, 128, CV_8UC1), b(128, 128, CV_8UC1);
  const std::size_t n = a.total();
  for (std::size_t i = 0; i < n; ++i) {
    a.data[i] = data[i % size];
    b.data[i] = data[(i + n) % size];
  }
  check(p.process(a));
  check(p.process(b));
  return 0;
}
