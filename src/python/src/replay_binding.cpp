#include <nanobind/eigen/dense.h>
#include <nanobind/ndarray.h>
#include <nanobind/stl/filesystem.h>
#include <nanobind/stl/optional.h>
#include <nanobind/stl/string.h>
#include <nanobind/stl/vector.h>

#include <algorithm>
#include <cstring>
#include <span>

#include "bindings.hpp"
#include "result_convert.hpp"
#include "omnipose/io/dataset.hpp"
#include "omnipose/io/replay.hpp"
#include "omnipose/unwrapper.hpp"

namespace nb = nanobind;

namespace omnipose::python {
namespace {

/// An array owned by Python, filled from `values` (row-major).
template <std::size_t N>
nb::ndarray<nb::numpy, double> ownedArray(std::vector<double> values,
                                          const std::size_t (&shape)[N]) {
  auto* data = new std::vector<double>(std::move(values));
  nb::capsule owner(data, [](void* p) noexcept { delete static_cast<std::vector<double>*>(p); });
  return nb::ndarray<nb::numpy, double>(data->data(), N, shape, owner);
}

/// Poses as (N, 4, 4) row-major and their timestamps as (N,).
void addPoses(nb::dict& d, const char* times_key, const char* poses_key,
              const std::vector<StampedPose>& poses) {
  std::vector<double> t, m;
  m.reserve(poses.size() * 16);
  for (const StampedPose& p : poses) {
    t.push_back(p.timestamp);
    const Eigen::Matrix4d a = p.pose.matrix();
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c) m.push_back(a(r, c));
  }
  d[times_key] = ownedArray(std::move(t), {poses.size()});
  d[poses_key] = ownedArray(std::move(m), {poses.size(), 4, 4});
}

/// A replay's outcome (replayDataset()) with what Python gets of each pose.
struct ReplayRun {
  std::vector<StampedPose> trajectory;           ///< the map pose
  std::vector<StampedPose> odometry_trajectory;  ///< the odometry's pose, per trajectory entry
  std::vector<std::string> states;  ///< per trajectory entry
  std::vector<double> sequences;    ///< frame index per trajectory entry
  std::vector<std::string> log;     ///< skipped / lost frames, as omnipose-replay logs them
  ReplayCounts counts;
  int gyro_frames = 0;
  std::vector<double> seconds;
};

/// Calls a Python function with each processed frame (the GIL taken for the call only). The
/// first exception it raises is kept, and no call is made after it; rethrow() raises it once
/// the replay is over.
class FrameCallback {
 public:
  explicit FrameCallback(nb::object function) : function_(std::move(function)) {}
  bool active() const { return function_.is_valid() && !function_.is_none(); }

  void operator()(int index, const DatasetFrame& frame, const OdometryResult& r,
                  const WindowGeometry& geometry) {
    if (!active() || failure_) return;
    FrameResult result = toFrameResult(r, frame.timestamp, geometry);
    nb::gil_scoped_acquire gil;
    try {
      function_(index, frame.path.string(), std::move(result));
    } catch (nb::python_error& e) {
      failure_.emplace(std::move(e));
    }
  }

  /// Raises what the function raised (call with the GIL held).
  void rethrow() {
    if (failure_) {
      nb::python_error e = std::move(*failure_);
      failure_.reset();
      throw e;
    }
  }

 private:
  nb::object function_;
  std::optional<nb::python_error> failure_;
};

/// omnipose-replay's loop (omnipose/io/replay.hpp) with the iFMI odometry. No Python object
/// is touched but by `on_frame`, which takes the GIL: it runs without it.
void runReplay(const Dataset& dataset, const OdometryOptions& options,
               std::span<const GyroSample> gyro, ReplayRun& run, FrameCallback& on_frame) {
  Odometry odometry(dataset.calibration, options);
  const WindowGeometry geometry = windowGeometry(dataset.calibration, odometry);
  run.counts = replayDataset(
      dataset, odometry, gyro, options.pipeline.unwrap.input, run.trajectory,
      [&](int i, const DatasetFrame& frame, const OdometryResult& r) {
        run.seconds.push_back(r.relative.timing.total);
        on_frame(i, frame, r, geometry);
        if (r.state == TrackState::kLost) return;  // no pose in the trajectory
        run.odometry_trajectory.push_back({frame.timestamp, r.pose});
        run.states.emplace_back(toString(r.state));
        run.sequences.push_back(i);
      },
      [&](const std::string& line) { run.log.push_back(line); });
  run.gyro_frames = static_cast<int>(odometry.gyroCounters().frames_with_gyro);
}

nb::dict replay(const std::filesystem::path& dataset_dir, const std::string& options_yaml,
                const std::string& origin, const std::optional<std::filesystem::path>& calibration,
                nb::object on_frame, const std::optional<std::filesystem::path>& base_dir) {
  const Dataset dataset = Dataset::open(dataset_dir, calibration);
  std::vector<std::string> warnings;
  const OdometryOptions options = parseOdometryOptions(
      options_yaml, origin, dataset.calibration, warnings, base_dir.value_or(""));
  if (const std::string assumed = dataset.assumptions(); !assumed.empty())
    warnings.push_back(assumed);
  warnings.insert(warnings.end(), dataset.warnings.begin(), dataset.warnings.end());
  std::string gyro_warning;
  const std::vector<GyroSample> gyro = datasetGyroSamples(dataset, gyro_warning);
  if (!gyro_warning.empty()) warnings.push_back(gyro_warning);
  ReplayRun run;
  FrameCallback callback(std::move(on_frame));
  {
    nb::gil_scoped_release release;
    runReplay(dataset, options, gyro, run, callback);
  }
  callback.rethrow();
  nb::dict d;
  addPoses(d, "timestamps", "poses", run.trajectory);
  nb::dict odometry_poses;
  addPoses(odometry_poses, "timestamps", "poses", run.odometry_trajectory);
  d["odometry_poses"] = odometry_poses["poses"];
  d["sequences"] = ownedArray(std::move(run.sequences), {run.trajectory.size()});
  d["states"] = run.states;
  d["frames"] = static_cast<int>(dataset.frames.size());
  d["pairs"] = run.counts.pairs;
  d["skipped"] = run.counts.skipped;
  d["implausible"] = run.counts.implausible;
  d["lost"] = run.counts.lost;
  d["bridged"] = run.counts.bridged;
  d["gyro_frames"] = run.gyro_frames;
  double median = 0.0;
  if (!run.seconds.empty()) {
    std::nth_element(run.seconds.begin(), run.seconds.begin() + run.seconds.size() / 2,
                     run.seconds.end());
    median = run.seconds[run.seconds.size() / 2];
  }
  d["median_seconds_per_frame"] = median;
  d["log"] = run.log;
  d["warnings"] = warnings;
  return d;
}

nb::dict openDataset(const std::filesystem::path& dataset_dir,
                     const std::optional<std::filesystem::path>& calibration) {
  const Dataset dataset = Dataset::open(dataset_dir, calibration);
  nb::dict d;
  d["root"] = dataset.root;
  d["calibration"] = dataset.calibration;
  std::vector<std::filesystem::path> paths;
  std::vector<double> times, exposures;
  for (const DatasetFrame& f : dataset.frames) {
    paths.push_back(f.path);
    times.push_back(f.timestamp);
    exposures.push_back(f.exposure_s);
  }
  d["frames"] = paths;
  d["timestamps"] = ownedArray(std::move(times), {dataset.frames.size()});
  d["exposures"] = ownedArray(std::move(exposures), {dataset.frames.size()});
  d["timestamps_from_file"] = dataset.timestamps_from_file;
  d["gyro_file"] = dataset.gyro_file;
  d["warnings"] = dataset.warnings;
  if (dataset.groundtruth) {
    nb::dict gt;
    addPoses(gt, "timestamps", "poses", *dataset.groundtruth);
    d["groundtruth"] = gt;
  } else {
    d["groundtruth"] = nb::none();
  }
  return d;
}

}  // namespace

void bindReplay(nb::module_& m) {
  m.def("_replay", &replay, nb::arg("dataset_dir"), nb::arg("options_yaml"), nb::arg("origin"),
        nb::arg("calibration") = nb::none(), nb::arg("on_frame") = nb::none(),
        nb::arg("base_dir") = nb::none(),
        "omnipose-replay's loop over a dataset directory (omnipose.replay() wraps it); "
        "on_frame(index, path, FrameResult) is called with every processed frame.");
  m.def("_open_dataset", &openDataset, nb::arg("dataset_dir"), nb::arg("calibration") = nb::none(),
        "A dataset directory as the library reads it (omnipose.open_dataset() wraps it).");
}

}  // namespace omnipose::python
