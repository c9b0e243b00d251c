/// The module omnipose._omnipose: the C++ library's odometry, calibration and dataset reader
/// for Python (src/python/omnipose/__init__.py is the public face; DESIGN.md section on the
/// binding).
#include <nanobind/nanobind.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/filesystem.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>

#include <cstring>

#include "bindings.hpp"
#include "omnipose/config_error.hpp"
#include "omnipose/io/dataset.hpp"

namespace nb = nanobind;

namespace omnipose::python {
namespace {

/// A decoded frame (grey (H, W) or BGR (H, W, 3)) as a NumPy array that owns its pixels.
nb::ndarray<nb::numpy, std::uint8_t> readFramePy(const std::filesystem::path& path) {
  Expected<cv::Mat> image = readFrame(path);
  if (!image) {
    if (image.error().code() == ErrorCode::kNotFound)
    {
      PyErr_SetString(PyExc_FileNotFoundError, image.error().c_str());
      throw nb::python_error();
    }
    throw nb::value_error(image.error().c_str());
  }
  auto* mat = new cv::Mat(image->isContinuous() ? *image : image->clone());
  nb::capsule owner(mat, [](void* p) noexcept { delete static_cast<cv::Mat*>(p); });
  const std::size_t channels = static_cast<std::size_t>(mat->channels());
  const std::size_t shape[3] = {static_cast<std::size_t>(mat->rows),
                                static_cast<std::size_t>(mat->cols), channels};
  return nb::ndarray<nb::numpy, std::uint8_t>(mat->data, channels == 1 ? 2 : 3, shape, owner);
}

}  // namespace

void bindCalibration(nb::module_& m) {
  nb::exception<ConfigError>(m, "ConfigError", PyExc_ValueError);
  nb::class_<Calibration>(m, "Calibration",
                          "calibration.yaml: the lens and the panorama it is unwrapped to "
                          "(include/omnipose/calibration.hpp; DESIGN.md section 6).")
      .def_static("load", &Calibration::load, nb::arg("path"),
                  "Reads calibration.yaml and the files it names (relative to it). Raises "
                  "ConfigError (a ValueError) listing every problem, each naming the file and "
                  "the field (or line), a missing or unreadable file included.")
      .def_static("parse", &Calibration::parse, nb::arg("yaml_text"),
                  nb::arg("origin") = "<string>", nb::arg("base_dir") = std::filesystem::path(),
                  "Parses calibration YAML text; origin names it in messages; files it names "
                  "are relative to base_dir. Raises ConfigError like load().")
      .def("save", &Calibration::save, nb::arg("path"),
           "Writes the YAML (and the files it names) to path.")
      .def("to_yaml", &Calibration::toYaml, "The YAML text save() writes.")
      .def_prop_ro("frame_shape",
                   [](const Calibration& c) {
                     return std::make_tuple(c.omni.image_height, c.omni.image_width);
                   },
                   "(H, W) of the camera's frames, pixels.")
      .def_prop_ro("panorama_shape",
                   [](const Calibration& c) {
                     return std::make_tuple(c.panorama.height, c.panorama.width);
                   },
                   "(H, W) of the unwrapped panorama, pixels.")
      .def_prop_ro("readout_s", [](const Calibration& c) { return c.sensor.readout_s; },
                   "Rolling shutter's first-to-last row time, seconds (0: global shutter).")
      .def_prop_ro("has_imu", [](const Calibration& c) { return c.imu.has_value(); },
                   "Whether the calibration joins a gyro to the frames (its imu section).");
  m.def("read_frame", &readFramePy, nb::arg("path"),
        "Reads an 8-bit image as stored (grey (H, W), colour (H, W, 3) BGR) with the library's "
        "decoder. Raises FileNotFoundError for a missing file, ValueError naming the file otherwise.");
}

}  // namespace omnipose::python

NB_MODULE(_omnipose, m) {
  m.doc() = "omnipose's C++ library: odometry, calibration, datasets (use the package omnipose).";
  m.attr("__version__") = OMNIPOSE_VERSION;
  omnipose::python::bindCalibration(m);
  omnipose::python::bindResult(m);
  omnipose::python::bindOdometry(m);
  omnipose::python::bindReplay(m);
  omnipose::python::bindPanorama(m);
}
