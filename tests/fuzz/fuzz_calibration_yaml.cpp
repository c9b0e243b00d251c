// calibration.yaml parser: any text either parses into a calibration that validates, or
// throws CalibrationError (naming the origin). Anything else (another exception, a crash,
// undefined behaviour, a huge allocation) is a defect.
#include <cstdint>
#include <string>

#include "omnipose/calibration.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  try {
    const omnipose::Calibration c = omnipose::Calibration::parse(text, "fuzz.yaml");
    if (!c.validate().empty()) __builtin_trap();  // parse() must not return an invalid one
    // What save() writes must read back.
    (void)omnipose::Calibration::parse(c.toYaml(), "roundtrip.yaml");
  } catch (const omnipose::CalibrationError& e) {
    if (std::string(e.what()).find("fuzz.yaml") == std::string::npos) __builtin_trap();
  }
  return 0;
}
