// Panorama (the lens calibration's unwrapping, for pictures of a run) and encode_jpeg.
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/string.h>

#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "bindings.hpp"
#include "frame_view.hpp"
#include "omnipose/unwrapper.hpp"

namespace nb = nanobind;

namespace omnipose::python {
namespace {

InputKind inputKind(const std::string& input) {
  if (input == "omni") return InputKind::kOmni;
  if (input == "panorama") return InputKind::kPanorama;
  throw nb::value_error(("input: expected \"omni\" or \"panorama\", got \"" + input + "\"").c_str());
}

/// The calibration's unwrapping (omnipose::Unwrapper): its lookup table is built once.
class PyPanorama {
 public:
  PyPanorama(const Calibration& calibration, const std::string& input)
      : unwrapper_(calibration, {.input = inputKind(input)}), panorama_(unwrapper_.makePanorama()) {}

  /// The frame's panorama, grey levels 0..255, float32 (H, W), a new array.
  nb::ndarray<nb::numpy, float, nb::ndim<2>> unwrap(nb::handle frame) {
    AnyArray array;
    const cv::Mat view = frameView(frame, unwrapper_.inputSize(), "frame", array);
    if (auto ok = unwrapper_.unwrap(view, panorama_); !ok)
      throw nb::value_error(("frame: " + std::string(ok.error().message())).c_str());
    auto* copy = new cv::Mat(panorama_.clone());
    nb::capsule owner(copy, [](void* p) noexcept { delete static_cast<cv::Mat*>(p); });
    const std::size_t shape[2] = {static_cast<std::size_t>(copy->rows),
                                  static_cast<std::size_t>(copy->cols)};
    return nb::ndarray<nb::numpy, float, nb::ndim<2>>(copy->ptr<float>(), 2, shape, owner);
  }

  nb::tuple shape() const {
    const cv::Size s = unwrapper_.panoramaSize();
    return nb::make_tuple(s.height, s.width);
  }

 private:
  Unwrapper unwrapper_;
  cv::Mat panorama_;
};

/// JPEG bytes of a uint8 image: (H, W) grey or (H, W, 3) BGR.
nb::bytes encodeJpeg(nb::handle image, int quality) {
  if (quality < 1 || quality > 100)
    throw nb::value_error(("quality: expected 1..100, got " + std::to_string(quality)).c_str());
  AnyArray array;
  if (!nb::try_cast(image, array))
    throw nb::type_error("image: expected a uint8 NumPy array (H, W) or (H, W, 3)");
  const bool colour = array.ndim() == 3 && array.shape(2) == 3;
  if (array.ndim() != 2 && !colour)
    throw nb::value_error("image: expected shape (H, W) or (H, W, 3)");
  const cv::Mat view = frameView(image, cv::Size(static_cast<int>(array.shape(1)),
                                                 static_cast<int>(array.shape(0))),
                                 "image", array);
  std::vector<std::uint8_t> bytes;
  if (!cv::imencode(".jpg", view, bytes, {cv::IMWRITE_JPEG_QUALITY, quality}))
    throw std::runtime_error("image: the JPEG encoder failed");
  return nb::bytes(reinterpret_cast<const char*>(bytes.data()), bytes.size());
}

}  // namespace

void bindPanorama(nb::module_& m) {
  nb::class_<PyPanorama>(m, "Panorama",
                         "The calibration's cylindrical panorama of a frame (the pipeline's first "
                         "step), for pictures of a run. input: 'omni' (the donut image) or "
                         "'panorama' (frames that already are panoramas).")
      .def(nb::init<const Calibration&, const std::string&>(), nb::arg("calibration"),
           nb::arg("input") = "omni")
      .def("unwrap", &PyPanorama::unwrap, nb::arg("frame"),
           "The frame's panorama: float32 (H, W), grey levels 0..255. Raises TypeError or "
           "ValueError for a frame process() would refuse, ValueError for a black one.")
      .def_prop_ro("shape", &PyPanorama::shape, "The panorama's (H, W).");
  m.def("encode_jpeg", &encodeJpeg, nb::arg("image"), nb::arg("quality") = 85,
        "JPEG bytes of a uint8 image, (H, W) grey or (H, W, 3) BGR.");
}

}  // namespace omnipose::python
