#pragma once
// A rolling-shutter dataset with the robot's gyro, for the tests of the programs that read
// one (omnipose-replay, omniposed): the exact renderer's frames of a turn on a shaking base,
// the motion's velocity and acceleration continuous, imu.csv and the calibration's imu section.

#include <Eigen/Geometry>
#include <filesystem>
#include <sstream>
#include <vector>

#include "omnipose/calibration.hpp"
#include "omnipose/synth/gyro.hpp"
#include "omnipose/synth/synth.hpp"

namespace omnipose::testing {

/// What writeGyroDataset() wrote.
struct GyroDataset {
  Calibration calibration;           ///< as in its calibration.yaml (readout and imu)
  std::vector<GyroSample> samples;   ///< as in its imu.csv
  int frames = 0;
};

/// Writes `frames` - 1 steps of a 3 deg/frame turn at 30 fps on a base shaking 0.5 deg at
/// 1-9 Hz into `dir`, rendered from `photo` with a rolling shutter of 0.8 frame, and a 200 Hz
/// gyro of that motion (phone-class noise and bias) mounted 17 deg off, whose clock runs
/// `clock_ahead_s` ahead of the frames' (|.| <= 1 s: calibration imu.time_offset_s is minus it).
inline GyroDataset writeGyroDataset(const std::filesystem::path& dir,
                                    const std::filesystem::path& photo, int frames = 13,
                                    double clock_ahead_s = 0.008) {
  std::ostringstream script;
  script << "frame_rate: 30\n"
            "vibration: {amplitude_deg: 0.5, min_hz: 1, max_hz: 9, components: 3, seed: 5}\n"
            "segments:\n  - frames: "
         << frames - 1 << "\n    rotation: {axis: z, step_deg: 3, sign: positive}\n";
  const auto control = synth::generateTrajectory(synth::MotionScript::parse(script.str(), "turn"));
  constexpr auto kSpline = synth::Interpolation::kSpline;
  GyroDataset out;
  out.frames = static_cast<int>(control.size());
  Calibration& calibration = out.calibration;
  calibration.sensor.readout_s = 0.0267;
  synth::GyroSimulation gyro;
  gyro.time_offset_s = -clock_ahead_s;
  gyro.rotation = Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitY()));
  calibration.imu = ImuCalibration{};
  calibration.imu->rotation = gyro.rotation;
  calibration.imu->time_offset_s = gyro.time_offset_s;
  synth::RenderOptions ro;
  ro.supersample = 2;
  const synth::Renderer renderer(synth::Scene::load(photo, synth::SceneKind::kSphere),
                                 calibration, ro);
  synth::DatasetWriter writer(dir, calibration, 0);
  for (const auto& p : control) {
    const double t0 = p.timestamp;
    const cv::Mat image = renderer.render(
        [&](double t) { return synth::poseAtTime(control, t0 + t, kSpline); },
        calibration.sensor.readout_s);
    writer.addFrame(synth::degrade(image, {}, 0), {t0, synth::poseAtTime(control, t0, kSpline)});
  }
  out.samples = synth::simulateGyro(control, kSpline, gyro, control.front().timestamp - 0.1,
                                    control.back().timestamp + 0.1)
                    .samples;
  writer.writeGyro(out.samples);
  writer.finish();
  return out;
}

}  // namespace omnipose::testing
