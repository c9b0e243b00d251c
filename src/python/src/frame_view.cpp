#include "frame_view.hpp"

#include <cstdint>

namespace nb = nanobind;

namespace omnipose::python {
namespace {

std::string shapeText(const AnyArray& a) {
  std::string s = "(";
  for (std::size_t i = 0; i < a.ndim(); ++i)
    s += (i > 0 ? ", " : "") + std::to_string(a.shape(i));
  return s + (a.ndim() == 1 ? ",)" : ")");
}

std::string stridesText(const AnyArray& a) {
  std::string s = "(";
  for (std::size_t i = 0; i < a.ndim(); ++i)
    s += (i > 0 ? ", " : "") + std::to_string(a.stride(i));  // elements of one byte: bytes
  return s + ")";
}

std::string expectedText(const char* what, cv::Size size) {
  const std::string hw = std::to_string(size.height) + ", " + std::to_string(size.width);
  return std::string(what) + ": expected a uint8 array of shape (" + hw + ") (grey), (" + hw +
         ", 3) (BGR) or (" + hw + ", 4) (BGRA)";
}

}  // namespace

std::string dtypeName(const AnyArray& a) {
  const nb::dlpack::dtype t = a.dtype();
  const char* kind = "unknown";
  switch (static_cast<nb::dlpack::dtype_code>(t.code)) {
    case nb::dlpack::dtype_code::Int: kind = "int"; break;
    case nb::dlpack::dtype_code::UInt: kind = "uint"; break;
    case nb::dlpack::dtype_code::Float: kind = "float"; break;
    case nb::dlpack::dtype_code::Complex: kind = "complex"; break;
    case nb::dlpack::dtype_code::Bool: return "bool";
    default: break;
  }
  return kind + std::to_string(t.bits);
}

cv::Mat frameView(nb::handle frame, cv::Size expected, const char* what, AnyArray& a) {
  // An array of any dtype and layout, without conversion: a copy is never made here.
  if (!nb::try_cast(frame, a, false))
    throw nb::type_error((expectedText(what, expected) + ", got " +
                          nb::type_name(frame.type()).c_str())
                             .c_str());
  if (a.dtype() != nb::dtype<std::uint8_t>())
    throw nb::type_error(
        (expectedText(what, expected) + ", got " + dtypeName(a) + " " + shapeText(a)).c_str());
  const std::size_t channels = a.ndim() == 3 ? a.shape(2) : 1;
  const bool shape_ok = (a.ndim() == 2 || (a.ndim() == 3 && (channels == 3 || channels == 4))) &&
                        a.shape(0) == static_cast<std::size_t>(expected.height) &&
                        a.shape(1) == static_cast<std::size_t>(expected.width);
  if (!shape_ok)
    throw nb::value_error(
        (expectedText(what, expected) + " (the calibration's frame size), got uint8 " +
         shapeText(a))
            .c_str());
  // Rows may be apart (a slice of rows), a row's pixels may not: cv::Mat has one row step.
  const std::int64_t row_step = a.stride(0);
  const bool layout_ok = (a.ndim() == 2 ? a.stride(1) == 1
                                        : a.stride(2) == 1 && a.stride(1) == std::int64_t(channels)) &&
                         row_step >= std::int64_t(expected.width * channels);
  if (!layout_ok)
    throw nb::value_error((std::string(what) + ": expected each row's pixels contiguous in memory "
                           "(a C-contiguous array or a slice of its rows), got strides " +
                           stridesText(a) + " bytes: pass numpy.ascontiguousarray(" + what + ")")
                              .c_str());
  void* data = const_cast<void*>(static_cast<const void*>(a.data()));
  return cv::Mat(expected.height, expected.width, CV_8UC(static_cast<int>(channels)), data,
                 static_cast<std::size_t>(row_step));
}

}  // namespace omnipose::python
