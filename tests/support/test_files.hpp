#pragma once
/// \file test_files.hpp
/// File helpers every test may use (omnipose_add_test puts tests/support on the include
/// path). Header-only and light: no LCM, no daemon.

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace omnipose::testing {

/// The whole content of `path`; "" when it cannot be read (the test's assertion on the
/// content then says what is missing).
inline std::string readText(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

}  // namespace omnipose::testing
