#pragma once
/// \file quiet_opencv.hpp
/// For the programs that decode images: they report every unreadable file themselves, by
/// name; OpenCV's own warnings ("imdecode_(''): can't read header") would only repeat them
/// without it. Errors still reach the terminal.

#include <opencv2/core/utils/logger.hpp>

namespace omnipose::tools {

inline void quietOpenCvWarnings() {
  cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);
}

}  // namespace omnipose::tools
