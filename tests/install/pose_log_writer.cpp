// Writes an LCM log the way omniposed does with `lcm: {url: "file:///...?mode=w"}`: through
// LCM's file provider, a status_t on OMNI_STATUS, then two pose_t on OMNI_POSE. The decoders
// (decode_pose_log.py, DecodePoseLog.java) check the values set here:
//   pose k (k = 0, 1): sequence 41 + k, reference_sequence 40 + k, status STATUS_OK then
//   STATUS_DEGRADED, orientation the unit quaternion of (0.1 + 0.2 k) rad about (1, 2, 2) / 3,
//   covariance[i] = i * 1e-3, windows_used 30 + k of windows_total 32, residual_px 0.5.
// usage: omnipose-test-pose-log-writer <log file>
#include <cmath>
#include <cstdio>
#include <string>

#include <lcm/lcm-cpp.hpp>
#include <omnipose/pose_t.hpp>
#include <omnipose/status_t.hpp>

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s <log file>\n", argv[0]);
    return 2;
  }
  lcm::LCM lcm("file://" + std::string(argv[1]) + "?mode=w");
  if (!lcm.good()) {
    std::fprintf(stderr, "cannot open the LCM log %s for writing\n", argv[1]);
    return 1;
  }
  omnipose::status_t status{};
  status.utime = 1'700'000'000'000'000;
  status.frames_processed = 2;
  status.source_state = omnipose::status_t::SOURCE_STREAMING;
  status.source = "file /data/run1 (2 frames)";
  if (lcm.publish("OMNI_STATUS", &status) != 0) return 1;

  for (int k = 0; k < 2; ++k) {
    omnipose::pose_t pose{};
    pose.utime = 1'700'000'000'100'000 + 33'333 * k;
    pose.sequence = 41 + k;
    pose.reference_sequence = 40 + k;
    pose.source_index = k;
    pose.source_timestamp = 0.1 * k;
    pose.segment = 0;
    pose.status = k == 0 ? omnipose::pose_t::STATUS_OK : omnipose::pose_t::STATUS_DEGRADED;
    const double angle = 0.1 + 0.2 * k;
    const double axis[3] = {1.0 / 3.0, 2.0 / 3.0, 2.0 / 3.0};
    pose.orientation[0] = std::cos(angle / 2.0);
    for (int i = 0; i < 3; ++i) {
      pose.orientation[i + 1] = std::sin(angle / 2.0) * axis[i];
      pose.rotation_vector[i] = angle * axis[i];
      pose.translation_direction[i] = axis[i];
      pose.position[i] = 0.25 * k * axis[i];
    }
    pose.tau_norm = 0.02;
    for (int i = 0; i < 36; ++i) pose.covariance[i] = i * 1e-3;
    pose.residual_px = 0.5F;
    pose.windows_used = static_cast<int16_t>(30 + k);
    pose.windows_total = 32;
    pose.frames_skipped = 0;
    pose.processing_time_s = 0.004F;
    if (lcm.publish("OMNI_POSE", &pose) != 0) return 1;
  }
  return 0;
}
