#pragma once
/// \file pose_graph.hpp
/// A pose graph over places (private to the core library): nodes are camera poses in the
/// map frame, edges relative poses between two nodes (the odometry between consecutive
/// places, or a loop closure: a place registered against another). Solved in two linear
/// steps instead of one nonlinear one (Carlone et al., ICRA 2015, "Initialization techniques
/// for 3D SLAM"): the rotations by Gauss-Newton on SO(3) (rotation averaging, a few
/// iterations from the odometry's rotations), then the positions by linear least squares
/// given the rotations. With the rotations known the positions' problem is linear and exact;
/// what the robot's controller feels, the heading, is the rotations' problem.
///
/// Why not Ceres: a graph of at most a few hundred nodes whose every edge is a relative
/// rotation is a dense 3n x 3n normal system solved in place (Eigen's LLT on preallocated
/// storage, no allocation after construction); Ceres would bring a dependency, allocations
/// per solve and a nonlinear SE(3) problem whose translations are only known up to the
/// scene's scale anyway.
///
/// Node 0 (the first node added) fixes the gauge: it keeps its pose, and is never removed.
/// Realtime: the constructor allocates everything for `max_nodes` nodes and `max_edges`
/// edges; nothing else allocates or throws.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vector>

namespace omnipose::map {

class PoseGraph {
 public:
  struct Edge {
    int from = -1, to = -1;
    /// Pose of node `to` in node `from`'s frame (positions in scene distances).
    Eigen::Isometry3d relative = Eigen::Isometry3d::Identity();
    double rotation_sigma = 1.0;  ///< radians, one sigma, each axis
    double position_sigma = 1.0;  ///< scene distances, one sigma, each axis
    bool loop = false;            ///< a loop closure (else the odometry between places)
  };

  /// Throws std::invalid_argument unless 1 <= max_nodes <= 4096 and max_edges >= max_nodes.
  PoseGraph(int max_nodes, int max_edges);

  /// A new node at `pose` (its initial estimate); its id, or -1 when every node is taken.
  int addNode(const Eigen::Isometry3d& pose);
  /// Removes node `id` (not node 0). Its neighbours stay connected: each is joined to the
  /// neighbour closest to the removed node by the composition of the two edges through it
  /// (their variances added), so the graph's constraints survive, somewhat weakened.
  void removeNode(int id);
  /// Adds `edge`; a loop edge between two nodes already joined by a loop edge replaces it
  /// (the newer measurement). False when either node is unknown, from == to, or the edges
  /// are all taken.
  bool addEdge(const Edge& edge);
  /// Solves the graph (node 0 fixed): rotations, then positions. Nodes no edge reaches
  /// from node 0 keep their pose.
  void solve(int rotation_iterations = 5);
  /// Forgets every node and edge.
  void clear();

  bool alive(int id) const { return id >= 0 && id < static_cast<int>(alive_.size()) && alive_[id]; }
  const Eigen::Isometry3d& pose(int id) const { return poses_[static_cast<std::size_t>(id)]; }
  int nodeCount() const { return nodes_; }
  int edgeCount() const { return static_cast<int>(edge_count_); }
  /// Edge `i`, 0 <= i < edgeCount() (the order changes as nodes are removed).
  const Edge& edge(int i) const { return edges_[static_cast<std::size_t>(i)]; }
  int maxNodes() const { return static_cast<int>(alive_.size()); }
  int maxEdges() const { return static_cast<int>(edges_.size()); }

 private:
  /// Numbers the nodes node 0 reaches (index_[id], -1 for none and node 0); their count.
  int indexReachable();
  void solveRotations(int unknowns, int iterations);
  void solvePositions(int unknowns);

  std::vector<Eigen::Isometry3d> poses_;
  std::vector<unsigned char> alive_;
  std::vector<Edge> edges_;
  std::size_t edge_count_ = 0;
  int nodes_ = 0;
  std::vector<int> index_, queue_;
  /// Normal equations, solved in place (the largest system: 3 max_nodes unknowns).
  Eigen::MatrixXd H_;
  Eigen::VectorXd b_;
  std::vector<int> neighbours_;  ///< removeNode()'s scratch
};

}  // namespace omnipose::map
