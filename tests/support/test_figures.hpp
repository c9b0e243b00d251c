#pragma once
/// \file test_figures.hpp
/// Figures a test measures go to gtest, not stdout: as test properties named
/// after what they measure (RecordProperty: in the report of --gtest_output=xml or json, not
/// in the console log), and, where a reader of a failing test's log needs the figure, in the
/// assertion's message or a SCOPED_TRACE as well. RecordProperty takes a string or an int, so
/// a double is written with a fixed number of decimals. omnipose_add_test puts tests/support
/// on the include path.

#include <gtest/gtest.h>

#include <iomanip>
#include <sstream>
#include <string>

namespace omnipose::testing {

/// `value` with `decimals` digits after the point ("0.0213").
inline std::string fixed(double value, int decimals) {
  std::ostringstream text;
  text << std::fixed << std::setprecision(decimals) << value;
  return text.str();
}

/// Records `value` as the current test's property `name` (decimals as in fixed()); returns
/// it, so a figure is measured and recorded in one statement.
inline double recordFigure(const std::string& name, double value, int decimals) {
  ::testing::Test::RecordProperty(name, fixed(value, decimals));
  return value;
}

}  // namespace omnipose::testing
