#include "map/pose_graph.hpp"

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "omnipose/so3.hpp"

namespace omnipose::map {

namespace {
/// A rotation update below this (radians, largest of any node) ends the iterations.
constexpr double kConverged = 1e-10;
}  // namespace

PoseGraph::PoseGraph(int max_nodes, int max_edges) {
  if (max_nodes < 1 || max_nodes > 4096 || max_edges < max_nodes)
    throw std::invalid_argument("PoseGraph: " + std::to_string(max_nodes) + " nodes and " +
                                std::to_string(max_edges) +
                                " edges (1 to 4096 nodes, at least as many edges)");
  const auto n = static_cast<std::size_t>(max_nodes);
  poses_.assign(n, Eigen::Isometry3d::Identity());
  alive_.assign(n, 0);
  edges_.resize(static_cast<std::size_t>(max_edges));
  index_.assign(n, -1);
  queue_.reserve(n);
  neighbours_.reserve(static_cast<std::size_t>(max_edges));
  H_.setZero(3 * max_nodes, 3 * max_nodes);
  b_.setZero(3 * max_nodes);
}

int PoseGraph::addNode(const Eigen::Isometry3d& pose) {
  const auto free = std::find(alive_.begin(), alive_.end(), 0);
  if (free == alive_.end()) return -1;
  const auto id = static_cast<int>(free - alive_.begin());
  *free = 1;
  poses_[static_cast<std::size_t>(id)] = pose;
  ++nodes_;
  return id;
}

bool PoseGraph::addEdge(const Edge& edge) {
  if (!alive(edge.from) || !alive(edge.to) || edge.from == edge.to) return false;
  if (edge.loop) {
    for (std::size_t e = 0; e < edge_count_; ++e) {
      Edge& old = edges_[e];
      if (old.loop && ((old.from == edge.from && old.to == edge.to) ||
                       (old.from == edge.to && old.to == edge.from))) {
        old = edge;
        return true;
      }
    }
  }
  if (edge_count_ == edges_.size()) return false;
  edges_[edge_count_++] = edge;
  return true;
}

void PoseGraph::removeNode(int id) {
  if (id == 0 || !alive(id)) return;
  // The edges through `id`, seen from it: the other node and the pose of that node in id's
  // frame. The neighbour joined most tightly becomes the hub the others are joined to.
  neighbours_.clear();
  int hub = -1;
  for (std::size_t e = 0; e < edge_count_; ++e) {
    const Edge& edge = edges_[e];
    if (edge.from != id && edge.to != id) continue;
    neighbours_.push_back(static_cast<int>(e));
    if (hub < 0 || edge.rotation_sigma < edges_[static_cast<std::size_t>(hub)].rotation_sigma)
      hub = static_cast<int>(e);
  }
  const auto seen_from_id = [&](const Edge& edge) {
    return edge.from == id ? edge.relative : edge.relative.inverse();
  };
  const auto other = [&](const Edge& edge) { return edge.from == id ? edge.to : edge.from; };
  // The composed edges are written over the removed ones (as many or fewer).
  std::size_t write = 0;
  if (hub >= 0) {
    const Edge h = edges_[static_cast<std::size_t>(hub)];
    const Eigen::Isometry3d hub_from_id = seen_from_id(h).inverse();
    for (const int e : neighbours_) {
      const Edge edge = edges_[static_cast<std::size_t>(e)];
      if (e == hub || other(edge) == other(h)) continue;
      // Written over an edge already read (write <= this one's place in neighbours_).
      edges_[static_cast<std::size_t>(neighbours_[write++])] = {
          other(h), other(edge), hub_from_id * seen_from_id(edge),
          std::hypot(h.rotation_sigma, edge.rotation_sigma),
          std::hypot(h.position_sigma, edge.position_sigma), false};
    }
  }
  // Drop the edges not reused (from the back, keeping the list dense).
  for (std::size_t k = neighbours_.size(); k-- > write;) {
    const auto e = static_cast<std::size_t>(neighbours_[k]);
    edges_[e] = edges_[--edge_count_];
  }
  alive_[static_cast<std::size_t>(id)] = 0;
  --nodes_;
}

void PoseGraph::clear() {
  std::fill(alive_.begin(), alive_.end(), 0);
  edge_count_ = 0;
  nodes_ = 0;
}

int PoseGraph::indexReachable() {
  std::fill(index_.begin(), index_.end(), -1);
  if (!alive(0)) return 0;
  queue_.clear();
  queue_.push_back(0);
  int unknowns = 0;
  for (std::size_t head = 0; head < queue_.size(); ++head) {
    const int node = queue_[head];
    for (std::size_t e = 0; e < edge_count_; ++e) {
      const Edge& edge = edges_[e];
      const int next = edge.from == node ? edge.to : edge.to == node ? edge.from : -1;
      if (next <= 0 || index_[static_cast<std::size_t>(next)] >= 0) continue;
      index_[static_cast<std::size_t>(next)] = unknowns++;
      queue_.push_back(next);
    }
  }
  return unknowns;
}

void PoseGraph::solve(int rotation_iterations) {
  const int unknowns = indexReachable();
  if (unknowns == 0) return;
  solveRotations(unknowns, rotation_iterations);
  solvePositions(unknowns);
}

void PoseGraph::solveRotations(int unknowns, int iterations) {
  // Residual of edge (i, j): r = log(Z^T R_i^T R_j); with R_i <- R_i exp(d_i) it moves by
  // d_j - R_j^T R_i d_i (to first order, the right Jacobian of a small residual taken as I).
  const int n = 3 * unknowns;
  for (int it = 0; it < iterations; ++it) {
    Eigen::Ref<Eigen::MatrixXd> H = H_.topLeftCorner(n, n);
    Eigen::Ref<Eigen::VectorXd> b = b_.head(n);
    H.setZero();
    b.setZero();
    for (std::size_t e = 0; e < edge_count_; ++e) {
      const Edge& edge = edges_[e];
      const int i = index_[static_cast<std::size_t>(edge.from)];
      const int j = index_[static_cast<std::size_t>(edge.to)];
      if ((edge.from != 0 && i < 0) || (edge.to != 0 && j < 0)) continue;  // not reached
      const Eigen::Matrix3d& Ri = poses_[static_cast<std::size_t>(edge.from)].linear();
      const Eigen::Matrix3d& Rj = poses_[static_cast<std::size_t>(edge.to)].linear();
      const Eigen::Vector3d r =
          rotationVector(edge.relative.linear().transpose() * Ri.transpose() * Rj);
      const double w = 1.0 / (edge.rotation_sigma * edge.rotation_sigma);
      const Eigen::Matrix3d Ji = -Rj.transpose() * Ri;
      if (i >= 0) {
        H.block<3, 3>(3 * i, 3 * i) += w * Eigen::Matrix3d::Identity();
        b.segment<3>(3 * i) += w * Ji.transpose() * r;
      }
      if (j >= 0) {
        H.block<3, 3>(3 * j, 3 * j) += w * Eigen::Matrix3d::Identity();
        b.segment<3>(3 * j) += w * r;
      }
      if (i >= 0 && j >= 0) {
        H.block<3, 3>(3 * i, 3 * j) += w * Ji.transpose();
        H.block<3, 3>(3 * j, 3 * i) += w * Ji;
      }
    }
    Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>> llt(H);
    if (llt.info() != Eigen::Success) return;
    b = -b;
    llt.solveInPlace(b);
    double largest = 0.0;
    for (std::size_t id = 1; id < poses_.size(); ++id) {
      const int k = index_[id];
      if (k < 0) continue;
      const Eigen::Vector3d d = b.segment<3>(3 * k);
      largest = std::max(largest, d.norm());
      Eigen::Isometry3d& T = poses_[id];
      const Eigen::Matrix3d R = T.linear() * rotationFromVector(d);
      T.linear() = Eigen::Quaterniond(R).normalized().toRotationMatrix();
    }
    if (largest < kConverged) return;
  }
}

void PoseGraph::solvePositions(int unknowns) {
  // p_j - p_i = R_i t_ij for every edge, weighted: a graph Laplacian, one right-hand side
  // per axis.
  Eigen::Ref<Eigen::MatrixXd> L = H_.topLeftCorner(unknowns, unknowns);
  Eigen::Map<Eigen::MatrixXd> B(b_.data(), unknowns, 3);
  L.setZero();
  B.setZero();
  const Eigen::Vector3d origin = poses_[0].translation();
  for (std::size_t e = 0; e < edge_count_; ++e) {
    const Edge& edge = edges_[e];
    const int i = index_[static_cast<std::size_t>(edge.from)];
    const int j = index_[static_cast<std::size_t>(edge.to)];
    if ((edge.from != 0 && i < 0) || (edge.to != 0 && j < 0)) continue;
    const Eigen::Vector3d a =
        poses_[static_cast<std::size_t>(edge.from)].linear() * edge.relative.translation();
    const double w = 1.0 / (edge.position_sigma * edge.position_sigma);
    if (i >= 0) {
      L(i, i) += w;
      B.row(i) -= w * a.transpose();
    } else {
      B.row(j) += w * origin.transpose();
    }
    if (j >= 0) {
      L(j, j) += w;
      B.row(j) += w * a.transpose();
    } else {
      B.row(i) += w * origin.transpose();
    }
    if (i >= 0 && j >= 0) {
      L(i, j) -= w;
      L(j, i) -= w;
    }
  }
  Eigen::LLT<Eigen::Ref<Eigen::MatrixXd>> llt(L);
  if (llt.info() != Eigen::Success) return;
  llt.solveInPlace(B);
  for (std::size_t id = 1; id < poses_.size(); ++id)
    if (const int k = index_[id]; k >= 0) poses_[id].translation() = B.row(k).transpose();
}

}  // namespace omnipose::map
