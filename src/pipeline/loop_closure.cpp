#include "pipeline/loop_closure.hpp"

#include <algorithm>
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
  anchor_distance_ += (last_odometry_.inverse() * frame.odometry).translation().norm();
  ++anchor_frames_;
  last_odometry_ = frame.odometry;
  Update out;
  const bool steady = frame.turn_rate <= options_.max_turn_rate_rad_s;
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
          anchor_ = id;
          anchor_odometry_ = frame.odometry * M->inverse();
          anchor_distance_ = 0.0;
          anchor_frames_ = 0;
          loose_ = false;
          chain_serial_ = memory_.stored();
          memory_.touch(id);
          confirmed_ = 0;
          out.loop_closed = true;
          out.place_sequence = memory_[id].sequence;
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

std::optional<Eigen::Isometry3d> LoopClosure::verify(int id, const Eigen::Isometry3d& predicted,
                                                     const Frame& frame, double* rotation_sigma) {
  const map::Place& place = memory_[id];
  if (!registrar_.loadKeyframe(spare_slot_, place.panorama)) return std::nullopt;
  // The yaw from the whole ring, within reach of the prediction; roll and pitch predicted.
  const std::optional<double> ring = registrar_.ringYaw(spare_slot_, min_ring_peak_);
  if (!ring) return std::nullopt;
  const Eigen::Matrix3d& Rp = predicted.linear();
  const double yaw_change = wrapAngle(*ring - yawOf(Rp));
  if (std::abs(yaw_change) > options_.max_correction_rad) return std::nullopt;
  const Eigen::Matrix3d R0 = rotationFromVector(Eigen::Vector3d(0.0, 0.0, yaw_change)) * Rp;
  const std::optional<MotionEstimate> start = registrar_.alignedPass(R0, spare_slot_);
  if (!start || start->status == FitStatus::kLost) return std::nullopt;
  const PassResult pass = registrar_.secondRefine(*start, rotationFromVector(start->omega) * R0,
                                                  start->tau, spare_slot_);
  if (!pass.refined || pass.estimate.status != FitStatus::kOk ||
      pass.estimate.windows_used < kMinWindowShare * registrar_.windowCount())
    return std::nullopt;
  // With a rolling shutter the rotation is between the windows' mean capture times; the
  // place's turn rate and this frame's move it to the timestamps.
  Eigen::Matrix3d R = pass.rotation;
  if (const double s = registrar_.meanWindowTime(); s != 0.0 && !pass.gyro_rows)
    R = rotationFromVector(Eigen::Vector3d(0.0, 0.0, (place.yaw_rate - frame.yaw_rate) * s)) * R;
  if (rotationVector(Rp.transpose() * R).norm() > options_.max_correction_rad) return std::nullopt;
  const Eigen::Isometry3d M = isometry(R, pass.estimate.tau);
  if ((M.translation() - predicted.translation()).norm() > options_.search_radius)
    return std::nullopt;
  const double variance = pass.estimate.covariance.topLeftCorner<3, 3>().trace() / 3.0;
  *rotation_sigma = std::clamp(std::sqrt(std::max(variance, 0.0)), kMinLoopSigma, kMaxLoopSigma);
  return M;
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
}

}  // namespace omnipose::pipeline
