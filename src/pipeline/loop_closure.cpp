#include "pipeline/loop_closure.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <numbers>

#include "omnipose/so3.hpp"

namespace omnipose::pipeline {
namespace {

/// The newest places made since the last loop closure are not compared with a frame: the
/// odometry joins them to it already.
constexpr long kNewestPlaces = 5;
/// Two matches in a row confirm each other when their corrections of the map's rotation
/// differ by at most this, radians (0.3 deg).
constexpr double kAgreeRad = 0.005;
/// A match needs at least this share of the windows in its fit.
constexpr double kMinWindowShare = 0.5;
/// The odometry's rotation drift assumed between places: per scene distance travelled and
/// per square root of a frame, radians; with a broken link (a new segment) a loose joint.
constexpr double kDriftPerDistance = 0.01;
constexpr double kDriftPerFrame = 3e-4;
constexpr double kLooseSigma = 10.0;
/// A registration's rotation sigma is taken within these bounds, radians.
constexpr double kMinLoopSigma = 5e-4, kMaxLoopSigma = 5e-3;
/// Matches in a row, at least, that anchor a loaded map (relocalisation).
constexpr int kRelocaliseConfirmations = 3;

double yawOf(const Eigen::Matrix3d& R) { return std::atan2(R(1, 0), R(0, 0)); }

double wrapAngle(double a) { return std::remainder(a, 2.0 * std::numbers::pi); }

}  // namespace

LoopClosure::LoopClosure(const LoopClosureOptions& options, FrameRegistrar& registrar,
                         int spare_slot, double min_ring_peak)
    : options_(options),
      registrar_(registrar),
      spare_slot_(spare_slot),
      min_ring_peak_(min_ring_peak),
      memory_(options.max_places, registrar.panorama().size()),
      signer_(registrar.panorama().size()),
      graph_(options.max_places, 4 * options.max_places) {}

Eigen::Isometry3d LoopClosure::correction() const {
  if (anchor_ < 0) return Eigen::Isometry3d::Identity();
  return graph_.pose(anchor_) * anchor_odometry_.inverse();
}

LoopClosure::Update LoopClosure::hold(const Eigen::Isometry3d& odometry, bool broken) {
  if (broken) loose_ = true;
  last_odometry_ = odometry;
  confirmed_ = 0;
  Update out;
  out.correction = correction();
  out.map_pose = out.correction * odometry;
  return out;
}

LoopClosure::Update LoopClosure::update(const Frame& frame) {
  const double step = (last_odometry_.inverse() * frame.odometry).translation().norm();
  anchor_distance_ += step;
  ++anchor_frames_;
  last_odometry_ = frame.odometry;
  Update out;
  const bool steady = frame.turn_rate <= options_.max_turn_rate_rad_s;
  if (relocalising_) {
    relocalise_distance_ += step;
    if (steady && --frames_to_check_ <= 0) {
      frames_to_check_ = options_.check_interval;
      if (!relocalise(frame, out) && relocalise_checks_ >= kRelocaliseChecks &&
          relocalise_distance_ >= options_.search_radius) {
        clear();  // not a place of the loaded map: a new map from here
        last_odometry_ = frame.odometry;
      }
    }
    if (relocalising_) {
      out.map_pose = frame.odometry;
      return out;
    }
    out.correction = correction();
    out.map_pose = out.correction * frame.odometry;
    if (out.loop_closed) return out;
  }
  Eigen::Isometry3d predicted = correction() * frame.odometry;
  if (steady && anchor_ >= 0 && --frames_to_check_ <= 0) {
    frames_to_check_ = options_.check_interval;
    if (const int id = candidate(predicted); id >= 0) {
      double sigma = kMaxLoopSigma;
      const Eigen::Isometry3d& place = graph_.pose(id);
      if (const auto M = verify(id, place.inverse() * predicted, frame, &sigma)) {
        const Eigen::Isometry3d measured = place * *M;
        const Eigen::Vector3d correction_now =
            rotationVector(measured.linear() * predicted.linear().transpose());
        confirmed_ = confirmed_ > 0 && (correction_now - pending_correction_).norm() <= kAgreeRad
                         ? confirmed_ + 1
                         : 1;
        pending_correction_ = correction_now;
        if (confirmed_ >= options_.confirmations) {
          if (id != anchor_) {
            // The odometry from the anchor to this frame, the match back to the place.
            const double drift = std::hypot(kDriftPerDistance * anchor_distance_,
                                            kDriftPerFrame * std::sqrt(double(anchor_frames_)));
            map::PoseGraph::Edge edge;
            edge.from = anchor_;
            edge.to = id;
            edge.relative = anchor_odometry_.inverse() * frame.odometry * M->inverse();
            edge.rotation_sigma = loose_ ? kLooseSigma : std::hypot(sigma, drift);
            edge.position_sigma = loose_ ? kLooseSigma : 0.01 + 0.05 * anchor_distance_;
            edge.loop = true;
            if (graph_.addEdge(edge)) graph_.solve();
          }
          anchorAt(id, frame.odometry * M->inverse(), out);
          predicted = correction() * frame.odometry;
        }
      } else {
        confirmed_ = 0;
      }
    }
  }
  if (steady && !out.loop_closed && !nearAPlace(predicted)) addPlace(frame, predicted);
  out.correction = correction();
  out.map_pose = out.correction * frame.odometry;
  return out;
}

bool LoopClosure::nearAPlace(const Eigen::Isometry3d& map_pose) const {
  for (int id = 0; id < memory_.capacity(); ++id)
    if (memory_[id].valid &&
        (graph_.pose(id).translation() - map_pose.translation()).norm() < options_.place_spacing)
      return true;
  return false;
}

int LoopClosure::candidate(const Eigen::Isometry3d& map_pose) {
  bool signed_frame = false;
  int best = -1;
  double best_similarity = options_.min_similarity;
  const long newest = std::max(chain_serial_, memory_.stored() - kNewestPlaces);
  for (int id = 0; id < memory_.capacity(); ++id) {
    const map::Place& p = memory_[id];
    if (!p.valid || id == anchor_ || p.serial > newest) continue;
    if ((graph_.pose(id).translation() - map_pose.translation()).norm() > options_.search_radius)
      continue;
    if (!signed_frame) {
      signer_.compute(registrar_.panorama(), signature_);
      signed_frame = true;
    }
    const double similarity = map::PlaceSignature::similarity(signature_, p.signature);
    if (similarity >= best_similarity) {
      best = id;
      best_similarity = similarity;
    }
  }
  return best;
}

std::optional<Eigen::Isometry3d> LoopClosure::registerAt(int id, const Eigen::Matrix3d& R0,
                                                         const Frame& frame,
                                                         double* rotation_sigma) {
  const map::Place& place = memory_[id];
  const std::optional<MotionEstimate> start = registrar_.alignedPass(R0, spare_slot_);
  if (!start || start->status == FitStatus::kLost) {
    ++counters_.fit_failed;
    return std::nullopt;
  }
  const PassResult pass = registrar_.secondRefine(*start, rotationFromVector(start->omega) * R0,
                                                  start->tau, spare_slot_);
  if (!pass.refined || pass.estimate.status != FitStatus::kOk ||
      pass.estimate.windows_used < kMinWindowShare * registrar_.windowCount()) {
    ++counters_.fit_failed;
    return std::nullopt;
  }
  // With a rolling shutter the rotation is between the windows' mean capture times; the
  // place's turn rate and this frame's move it to the timestamps.
  Eigen::Matrix3d R = pass.rotation;
  if (const double s = registrar_.meanWindowTime(); s != 0.0 && !pass.gyro_rows)
    R = rotationFromVector(Eigen::Vector3d(0.0, 0.0, (place.yaw_rate - frame.yaw_rate) * s)) * R;
  const double variance = pass.estimate.covariance.topLeftCorner<3, 3>().trace() / 3.0;
  *rotation_sigma = std::clamp(std::sqrt(std::max(variance, 0.0)), kMinLoopSigma, kMaxLoopSigma);
  return isometry(R, pass.estimate.tau);
}

std::optional<Eigen::Isometry3d> LoopClosure::verify(int id, const Eigen::Isometry3d& predicted,
                                                     const Frame& frame, double* rotation_sigma) {
  if (!registrar_.loadKeyframe(spare_slot_, memory_[id].panorama)) return std::nullopt;
  ++counters_.compared;
  // The yaw from the whole ring, within reach of the prediction; roll and pitch predicted.
  const std::optional<double> ring = registrar_.ringYaw(spare_slot_, min_ring_peak_);
  if (!ring) {
    ++counters_.no_ring_peak;
    return std::nullopt;
  }
  const Eigen::Matrix3d& Rp = predicted.linear();
  const double yaw_change = wrapAngle(*ring - yawOf(Rp));
  if (std::abs(yaw_change) > options_.max_correction_rad) {
    ++counters_.turned_too_far;
    return std::nullopt;
  }
  const Eigen::Matrix3d R0 = rotationFromVector(Eigen::Vector3d(0.0, 0.0, yaw_change)) * Rp;
  const std::optional<Eigen::Isometry3d> M = registerAt(id, R0, frame, rotation_sigma);
  if (!M) return std::nullopt;
  if (rotationVector(Rp.transpose() * M->linear()).norm() > options_.max_correction_rad) {
    ++counters_.turned_too_far;
    return std::nullopt;
  }
  if ((M->translation() - predicted.translation()).norm() > options_.search_radius) {
    ++counters_.too_far;
    return std::nullopt;
  }
  ++counters_.verified;
  return M;
}

std::optional<Eigen::Isometry3d> LoopClosure::recognise(int id, const Frame& frame) {
  if (!registrar_.loadKeyframe(spare_slot_, memory_[id].panorama)) return std::nullopt;
  ++counters_.compared;
  // Nothing predicts the heading: the ring's, level.
  const std::optional<double> ring = registrar_.ringYaw(spare_slot_, min_ring_peak_);
  if (!ring) {
    ++counters_.no_ring_peak;
    return std::nullopt;
  }
  const Eigen::Matrix3d R0 = rotationFromVector(Eigen::Vector3d(0.0, 0.0, *ring));
  double sigma = kMaxLoopSigma;
  const std::optional<Eigen::Isometry3d> M = registerAt(id, R0, frame, &sigma);
  if (!M) return std::nullopt;
  // The fit's rotation agrees with the ring's heading, and the frame is near the place.
  if (rotationVector(R0.transpose() * M->linear()).norm() > options_.max_correction_rad) {
    ++counters_.turned_too_far;
    return std::nullopt;
  }
  if (M->translation().norm() > options_.search_radius) {
    ++counters_.too_far;
    return std::nullopt;
  }
  ++counters_.verified;
  return M;
}

bool LoopClosure::relocalise(const Frame& frame, Update& out) {
  ++relocalise_checks_;
  signer_.compute(registrar_.panorama(), signature_);
  // The places most like the frame, best first.
  std::array<int, kRelocaliseCandidates> best;
  std::array<double, kRelocaliseCandidates> best_similarity;
  best.fill(-1);
  best_similarity.fill(options_.min_similarity);
  for (int id = 0; id < memory_.capacity(); ++id) {
    if (!memory_[id].valid) continue;
    const double similarity = map::PlaceSignature::similarity(signature_, memory_[id].signature);
    for (int k = 0; k < kRelocaliseCandidates; ++k) {
      if (similarity < best_similarity[static_cast<std::size_t>(k)]) continue;
      for (int j = kRelocaliseCandidates - 1; j > k; --j) {
        best[static_cast<std::size_t>(j)] = best[static_cast<std::size_t>(j - 1)];
        best_similarity[static_cast<std::size_t>(j)] = best_similarity[static_cast<std::size_t>(j - 1)];
      }
      best[static_cast<std::size_t>(k)] = id;
      best_similarity[static_cast<std::size_t>(k)] = similarity;
      break;
    }
  }
  // No place like the frame is no evidence either way: the matches so far stand.
  if (best[0] < 0) return false;
  // Each match implies the map's correction (map from odometry); all must agree.
  int matched = -1;
  Eigen::Isometry3d match_M = Eigen::Isometry3d::Identity();
  Eigen::Isometry3d correction_now = Eigen::Isometry3d::Identity();
  const auto agree = [&](const Eigen::Isometry3d& a, const Eigen::Isometry3d& b) {
    return rotationVector(a.linear().transpose() * b.linear()).norm() <= kAgreeRad &&
           (a.translation() - b.translation()).norm() <= options_.place_spacing;
  };
  for (const int id : best) {
    if (id < 0) break;
    const std::optional<Eigen::Isometry3d> M = recognise(id, frame);
    if (!M) continue;
    const Eigen::Isometry3d C = graph_.pose(id) * *M * frame.odometry.inverse();
    if (matched >= 0 && !agree(C, correction_now)) {
      ++counters_.disagreed;
      confirmed_ = 0;  // two places, two answers: a look-alike
      return false;
    }
    if (matched < 0) {
      matched = id;
      match_M = *M;
      correction_now = C;
    }
  }
  if (matched < 0) {
    confirmed_ = 0;
    return false;
  }
  confirmed_ = confirmed_ > 0 && agree(correction_now, pending_map_) ? confirmed_ + 1 : 1;
  pending_map_ = correction_now;
  if (confirmed_ < std::max(kRelocaliseConfirmations, options_.confirmations)) return false;
  relocalising_ = false;
  anchorAt(matched, frame.odometry * match_M.inverse(), out);
  return true;
}

void LoopClosure::anchorAt(int id, const Eigen::Isometry3d& place_odometry, Update& out) {
  anchor_ = id;
  anchor_odometry_ = place_odometry;
  anchor_distance_ = 0.0;
  anchor_frames_ = 0;
  loose_ = false;
  chain_serial_ = memory_.stored();
  memory_.touch(id);
  confirmed_ = 0;
  ++counters_.closures;
  out.loop_closed = true;
  out.place_sequence = memory_[id].sequence;
}

void LoopClosure::addPlace(const Frame& frame, const Eigen::Isometry3d& map_pose) {
  int id = graph_.addNode(map_pose);
  if (id < 0) {
    const int forget = memory_.leastRecentlyUsed(0, anchor_);
    if (forget < 0) return;
    graph_.removeNode(forget);
    memory_.remove(forget);
    id = graph_.addNode(map_pose);
    if (id < 0) return;
  }
  if (anchor_ >= 0) {
    map::PoseGraph::Edge edge;
    edge.from = anchor_;
    edge.to = id;
    edge.relative = anchor_odometry_.inverse() * frame.odometry;
    edge.rotation_sigma = loose_ ? kLooseSigma
                                 : std::max(std::hypot(kDriftPerDistance * anchor_distance_,
                                                       kDriftPerFrame * std::sqrt(double(anchor_frames_))),
                                            kMinLoopSigma);
    edge.position_sigma = loose_ ? kLooseSigma : 0.01 + 0.05 * anchor_distance_;
    graph_.addEdge(edge);
  }
  signer_.compute(registrar_.panorama(), signature_);
  memory_.store(id, registrar_.panorama(), signature_, frame.sequence, frame.time_s, frame.yaw_rate);
  anchor_ = id;
  anchor_odometry_ = frame.odometry;
  anchor_distance_ = 0.0;
  anchor_frames_ = 0;
  loose_ = false;
}

void LoopClosure::clear() {
  memory_.clear();
  graph_.clear();
  anchor_ = -1;
  anchor_odometry_ = Eigen::Isometry3d::Identity();
  last_odometry_ = Eigen::Isometry3d::Identity();
  anchor_distance_ = 0.0;
  anchor_frames_ = 0;
  loose_ = false;
  frames_to_check_ = 0;
  confirmed_ = 0;
  chain_serial_ = 0;
  relocalising_ = false;
  relocalise_checks_ = 0;
  relocalise_distance_ = 0.0;
}

void LoopClosure::snapshot(map::MapSnapshot& out) const { map::takeSnapshot(memory_, graph_, out); }

Expected<void> LoopClosure::restore(const map::MapSnapshot& snapshot) {
  clear();
  if (auto restored = map::restoreSnapshot(snapshot, memory_, graph_); !restored) return restored;
  relocalising_ = memory_.size() > 0;
  // Every loaded place may be compared with a frame.
  chain_serial_ = memory_.stored();
  return {};
}

}  // namespace omnipose::pipeline
