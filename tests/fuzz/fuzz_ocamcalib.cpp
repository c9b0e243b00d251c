// OCamCalib calib_results.txt parser: any text either parses into a model or throws
// std::runtime_error naming the origin. A model that parses is then used as the lens of a
// calibration (ring from its ROI line or a default): validate() must decide without UB, and
// a valid calibration's pixel <-> bearing round trip must not crash.
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>

#include "omnipose/calibration.hpp"
#include "omnipose/lens_model.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  omnipose::Calibration c;
  try {
    c.omni.ocamcalib = omnipose::OcamCalibModel::parse(text, "fuzz.txt");
  } catch (const std::runtime_error& e) {
    if (std::string(e.what()).find("fuzz.txt") == std::string::npos) __builtin_trap();
    return 0;
  }
  const omnipose::OcamCalibModel& m = *c.omni.ocamcalib;
  c.omni.model = omnipose::LensModelKind::kOcamCalib;
  c.omni.image_width = m.width;
  c.omni.image_height = m.height;
  c.omni.center_x = m.yc;
  c.omni.center_y = m.xc;
  c.omni.radius_inner = m.roi_min_radius.value_or(0.25 * m.height);
  c.omni.radius_outer = m.roi_max_radius.value_or(0.45 * m.height);
  if (!c.validate().empty()) return 0;
  for (double r = c.omni.radius_inner; r <= c.omni.radius_outer; r += (c.omni.radius_outer - c.omni.radius_inner) / 4) {
    const auto b = c.bearingOfPixel(c.omni.center_x + r, c.omni.center_y);
    if (!b || !b->allFinite()) continue;
    (void)c.pixelOfBearing(*b);
  }
  (void)c.omniPixel(10.0, 10.0);
  return 0;
}
