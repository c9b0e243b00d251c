// Linked into the test binaries and omnipose-synth of a ThreadSanitizer build only
// (OMNIPOSE_SANITIZE=thread, omnipose_tsan_serial_opencv() in cmake/omnipose_helpers.cmake).
// OpenCV's parallel_for_ runs on TBB, which is not built with TSan: its hand-over of work to
// the TBB workers is invisible, so every parallel loop (the renderer's) reads as races.
// cv::setNumThreads(0) makes OpenCV run its loops on the calling thread; what the TSan run
// checks is omnipose's own threads (the daemon's capture and processing threads, the
// pipeline's worker pool), which this does not touch.
#include <opencv2/core/utility.hpp>

namespace {
const bool kOpenCvSerial = [] {
  cv::setNumThreads(0);
  return true;
}();
}  // namespace
