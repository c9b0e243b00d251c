#include <nanobind/eigen/dense.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/tuple.h>
#include <nanobind/stl/vector.h>

#include <chrono>
#include <filesystem>
#include <limits>
#include <memory>
#include <mutex>
#include <optional>
#include <span>

#include "bindings.hpp"
#include "daemon/config.hpp"
#include "frame_view.hpp"
#include "omnipose/unwrapper.hpp"
#include "result_convert.hpp"

namespace nb = nanobind;

namespace omnipose::python {

OdometryOptions parseOdometryOptions(const std::string& options_yaml, const std::string& origin,
                                     const Calibration& calibration,
                                     std::vector<std::string>& warnings,
                                     const std::filesystem::path& base_dir) {
  const DaemonConfig config =
      DaemonConfig::parse(options_yaml, origin,
                          base_dir.empty() ? std::filesystem::current_path() : base_dir,
                          DaemonConfig::Use::kReplay);
  std::vector<std::string> problems = config.checkAgainst(calibration, origin);
  if (!problems.empty())
    throw ConfigError::listing(origin + ": invalid configuration", std::move(problems));
  warnings = config.warnings;
  return config.odometry();
}

namespace {

/// omnipose::Odometry for Python: checks frames against the calibration, releases the GIL
/// while a frame is processed, and refuses a second caller at the same time.
class PyOdometry {
 public:
  PyOdometry(const Calibration& calibration, const std::string& options_yaml,
             const std::string& origin)
      : options_(parseOdometryOptions(options_yaml, origin, calibration, warnings_)),
        frame_size_(inputFrameSize(calibration, options_.pipeline.unwrap.input)),
        odometry_(std::make_unique<Odometry>(calibration, options_)),
        geometry_(windowGeometry(calibration, *odometry_)) {}

  FrameResult process(nb::handle frame, double time_s, std::int64_t sequence, bool gap_before,
                      std::optional<double> exposure) {
    AnyArray array;  // holds the frame's array for the call
    const cv::Mat view = frameView(frame, frame_size_, "frame", array);
    std::unique_lock<std::mutex> lock = claim("process");
    Expected<OdometryResult> result;
    {
      nb::gil_scoped_release release;
      result = odometry_->process(
          view, {.time_s = time_s,
                 .sequence = sequence,
                 .gap_before = gap_before,
                 .exposure_s = exposure.value_or(std::numeric_limits<double>::quiet_NaN())});
    }
    return toFrameResult(result, time_s, geometry_);
  }

  /// Gyro samples: times (N,) seconds on the IMU's clock, rates (N, 3) rad/s about its axes.
  void addGyro(nb::ndarray<const double, nb::ndim<1>, nb::device::cpu> t,
               nb::ndarray<const double, nb::shape<-1, 3>, nb::device::cpu> rates) {
    if (t.shape(0) != rates.shape(0))
      throw nb::value_error(("add_gyro: t has " + std::to_string(t.shape(0)) +
                             " samples, rates " + std::to_string(rates.shape(0)))
                                .c_str());
    std::vector<GyroSample> samples(t.shape(0));
    const auto tv = t.view();
    const auto rv = rates.view();
    for (std::size_t i = 0; i < samples.size(); ++i)
      samples[i] = {tv(i), Eigen::Vector3d(rv(i, 0), rv(i, 1), rv(i, 2))};
    std::unique_lock<std::mutex> lock = claim("add_gyro");
    odometry_->addGyro(samples);
  }

  nb::dict gyroCounters() {
    const GyroCounters g = readClaimed("gyro_counters", &Odometry::gyroCounters);
    nb::dict d;
    d["accepted"] = g.accepted;
    d["not_finite"] = g.not_finite;
    d["too_fast"] = g.too_fast;
    d["out_of_order"] = g.out_of_order;
    d["clock_restarts"] = g.clock_restarts;
    d["frames_with_gyro"] = g.frames_with_gyro;
    d["frames_without_gyro"] = g.frames_without_gyro;
    d["frames_gyro_bridged"] = g.frames_gyro_bridged;
    d["bias_readings"] = g.bias_readings;
    d["exposures_refused"] = g.exposures_refused;
    d["bias"] = Eigen::Vector3d(g.bias);
    d["bias_sigma"] = g.bias_sigma;
    d["yaw_time_offset_s"] = g.yaw_time_offset_s;
    return d;
  }

  nb::dict loopClosureCounters() {
    const LoopClosureCounters c =
        readClaimed("loop_closure_counters", &Odometry::loopClosureCounters);
    nb::dict d;
    d["compared"] = c.compared;
    d["no_ring_peak"] = c.no_ring_peak;
    d["turned_too_far"] = c.turned_too_far;
    d["fit_failed"] = c.fit_failed;
    d["too_far"] = c.too_far;
    d["verified"] = c.verified;
    d["disagreed"] = c.disagreed;
    d["closures"] = c.closures;
    return d;
  }

  /// The same frames through Odometry::process in a C++ loop (GIL released): wall seconds.
  /// What the Python loop is compared with (tools/python_overhead.py).
  double processLoopSeconds(nb::ndarray<const std::uint8_t, nb::ndim<3>, nb::c_contig,
                                        nb::device::cpu> frames,
                            nb::ndarray<const double, nb::ndim<1>, nb::device::cpu> times) {
    if (frames.shape(0) != times.shape(0) ||
        frames.shape(1) != static_cast<std::size_t>(frame_size_.height) ||
        frames.shape(2) != static_cast<std::size_t>(frame_size_.width))
      throw nb::value_error("_process_loop_seconds: frames (N, H, W) of the frame size, times (N,)");
    std::unique_lock<std::mutex> lock = claim("_process_loop_seconds");
    nb::gil_scoped_release release;
    const auto start = std::chrono::steady_clock::now();
    for (std::size_t i = 0; i < frames.shape(0); ++i) {
      const cv::Mat view(frame_size_.height, frame_size_.width, CV_8UC1,
                         const_cast<std::uint8_t*>(frames.data()) + i * frames.stride(0));
      (void)odometry_->process(view, {times(i), static_cast<std::int64_t>(i), false});
    }
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  }

  void markGap() { auto lock = claim("mark_gap"); odometry_->markGap(); }
  void reset() { auto lock = claim("reset"); odometry_->reset(); }
  const Odometry& odometry() const { return *odometry_; }
  const std::vector<std::string>& warnings() const { return warnings_; }
  std::tuple<int, int> frameShape() const { return {frame_size_.height, frame_size_.width}; }

 private:
  /// One caller at a time (Odometry is not thread-safe and process() runs without the GIL).
  std::unique_lock<std::mutex> claim(const char* what) {
    std::unique_lock<std::mutex> lock(busy_, std::try_to_lock);
    if (!lock.owns_lock())
      throw std::runtime_error(std::string("Odometry.") + what +
                               ": another thread is using this Odometry (one caller at a time)");
    return lock;
  }
  /// A copy of what `read` returns (counters process() writes), taken while no other thread is
  /// inside a call; the lock is released before the copy is turned into Python objects.
  template <typename T>
  T readClaimed(const char* what, T (Odometry::*read)() const) {
    std::unique_lock<std::mutex> lock = claim(what);
    return ((*odometry_).*read)();
  }

  std::vector<std::string> warnings_;
  OdometryOptions options_;
  cv::Size frame_size_;
  std::unique_ptr<Odometry> odometry_;
  WindowGeometry geometry_;
  std::mutex busy_;
};

/// What process() makes of `frame`: the address of the cv::Mat header's pixels, its row step
/// in bytes and its channels (tests/python check that they are the array's own).
std::tuple<std::uintptr_t, std::size_t, int> frameViewOf(nb::handle frame,
                                                         const Calibration& calibration) {
  AnyArray array;
  const cv::Mat view =
      frameView(frame, inputFrameSize(calibration, InputKind::kOmni), "frame", array);
  return {reinterpret_cast<std::uintptr_t>(view.data), view.step[0], view.channels()};
}

}  // namespace

void bindOdometry(nb::module_& m) {
  m.def("_frame_view", &frameViewOf, nb::arg("frame"), nb::arg("calibration"));
  nb::class_<PyOdometry>(
      m, "Odometry",
      "The omnipose odometry (include/omnipose/odometry.hpp): frames in, per frame the motion "
      "since the previous frame and the chained pose out. omnipose.Odometry(calibration, "
      "**options) takes daemon.yaml's keys; this base class takes the options as daemon.yaml "
      "text. One caller at a time.")
      .def(nb::init<const Calibration&, const std::string&, const std::string&>(),
           nb::arg("calibration"), nb::arg("options_yaml"), nb::arg("origin"),
           "Raises ConfigError (a ValueError) listing every bad option, each named by its "
           "daemon.yaml key, and ValueError when the options do not fit the calibration.")
      .def("process", &PyOdometry::process, nb::arg("frame"), nb::arg("t"),
           nb::arg("sequence") = -1, nb::arg("gap_before") = false,
           nb::arg("exposure") = nb::none(),
           "Processes the next frame: a uint8 array (H, W) grey, (H, W, 3) BGR or (H, W, 4) BGRA "
           "of the calibration's frame size (frame_shape), read in place (no copy; rows may be "
           "strided) while the GIL is released: do not change it during the call. t: capture "
           "time, seconds (any epoch); sequence: the frame's number (-1: counted); gap_before: "
           "frames were lost since the previous call; exposure: how long its rows were exposed, "
           "seconds, as the camera reported it (None: the calibration's sensor.exposure_s; "
           "a value outside [0, 0.1] is counted in gyro_counters and not used). A rejected "
           "frame (black, a glitch) comes back with ok False. Raises TypeError (not a uint8 array) or ValueError (wrong shape "
           "or layout) naming what was expected.")
      .def("add_gyro", &PyOdometry::addGyro, nb::arg("t"), nb::arg("rates"),
           "Gyro samples before the frames they cover: t (N,) seconds on the IMU's clock, "
           "rates (N, 3) rad/s about the IMU's axes. Used when the calibration has an imu "
           "section; bad samples are counted (gyro_counters), never an error.")
      .def("gyro_counters", &PyOdometry::gyroCounters,
           "What became of the gyro samples and the frames that could use them (counts).")
      .def("loop_closure_counters", &PyOdometry::loopClosureCounters,
           "What the map made of the frames it registered against its places, counts since "
           "construction: 'compared' registrations, each ending in exactly one of 'verified' "
           "and the refusals 'no_ring_peak' (no clear heading on the ring), 'turned_too_far' "
           "(beyond max_correction_deg of the prediction), 'fit_failed' and 'too_far' (beyond "
           "search_radius); 'disagreed': relocalisation checks whose two places disagreed; "
           "'closures': loops closed. All 0 with loop_closure off.")
      .def("mark_gap", &PyOdometry::markGap, "A frame could not be read: the next is bridged.")
      .def("reset", &PyOdometry::reset, "Forgets everything: segment 0 starts again.")
      .def("_process_loop_seconds", &PyOdometry::processLoopSeconds, nb::arg("frames"),
           nb::arg("times"))
      .def_prop_ro("frame_shape", &PyOdometry::frameShape,
                   "(H, W) that process() takes: the calibration's image (input omni) or "
                   "panorama (input panorama).")
      .def_prop_ro("warnings", &PyOdometry::warnings,
                   "What the option parser changed (threads clamped to the cores).")
      .def_prop_ro("threads", [](const PyOdometry& o) { return o.odometry().threads(); },
                   "The pipeline's threads.")
      .def_prop_ro("active_threads", [](const PyOdometry& o) { return o.odometry().activeThreads(); },
                   "Threads taking part in the next frame.")
      .def_prop_ro("wisdom_loaded", [](const PyOdometry& o) { return o.odometry().wisdomLoaded(); },
                   "Whether the FFTW wisdom file was read.")
      .def_prop_ro("window_count", [](const PyOdometry& o) { return o.odometry().windowCount(); },
                   "Windows per panorama.");
}

}  // namespace omnipose::python
