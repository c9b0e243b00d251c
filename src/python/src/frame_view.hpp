#pragma once
/// \file frame_view.hpp
/// A NumPy frame as a cv::Mat header over its own pixels: no copy, the array must outlive the
/// header (the caller holds it for the call).

#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>

#include <opencv2/core.hpp>
#include <string>

namespace omnipose::python {

/// Any CPU array, read-only accepted (the pipeline never writes the frame).
using AnyArray = nanobind::ndarray<nanobind::ro, nanobind::device::cpu>;

/// `frame` as a cv::Mat of `expected` size (width x height) sharing its memory: a uint8 array
/// of shape (H, W) (grey), (H, W, 3) (BGR) or (H, W, 4) (BGRA) whose pixels are contiguous
/// within each row (C-contiguous, or a slice of rows of a larger array). `array` receives the
/// array (keep it alive while the header is used). Throws nb::type_error when `frame` is not
/// a CPU array or not uint8, nb::value_error for a wrong shape or a layout that would need a
/// copy; both messages name `what` and what was expected.
cv::Mat frameView(nanobind::handle frame, cv::Size expected, const char* what, AnyArray& array);

/// "uint8", "float64", ... for an array's dtype (NumPy's names).
std::string dtypeName(const AnyArray& array);

}  // namespace omnipose::python
