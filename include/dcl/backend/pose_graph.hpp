#pragma once

/// The pose graph every back-end stage works on (paper §III-C): nodes are
/// keyframe poses named by robot and keyframe (core::PoseKey), factors are
/// relative-pose measurements between them (odometry, intra-robot loops,
/// inter-robot loops). The local graph of one robot and the swarm's joint
/// graph are both a PoseGraph; the centralized solver and, later, DGS read it.
///
/// A factor measures T_from_to, the pose of `to` in the frame of `from`, with an
/// information matrix over the tangent [rho; phi] (g2o's EDGE_SE3:QUAT order).
/// Its residual is r = log(T_from_to^-1 T_world_from^-1 T_world_to) and its cost
/// r^T Omega r, g2o's chi-square convention, so costs compare with published ones.
///
/// A graph is built in code or from a file by io (io/pose_graph_g2o.hpp); the
/// back-end reads no file.

#include <Eigen/Geometry>
#include <cstddef>
#include <map>
#include <set>
#include <string_view>
#include <utility>
#include <vector>

#include <dcl/core/ids.hpp>
#include <dcl/core/se3.hpp>

namespace dcl::backend {

/// What a factor measures; the back-end treats loops differently (robust
/// losses, PCM for inter-robot ones), odometry never.
enum class FactorKind {
  odometry,    ///< consecutive keyframes of one robot
  intra_loop,  ///< a loop closure within one robot's trajectory
  inter_loop,  ///< a loop closure between two robots
};

/// "odometry", "intra_loop" or "inter_loop".
std::string_view toString(FactorKind kind);

/// True for intra_loop and inter_loop.
constexpr bool isLoop(FactorKind kind) {
  return kind != FactorKind::odometry;
}

/// One relative-pose measurement between two nodes.
struct Factor {
  core::PoseKey from;  ///< the node the measurement is expressed in
  core::PoseKey to;    ///< the measured node
  /// The pose of `to` in the frame of `from`.
  Eigen::Isometry3d T_from_to = Eigen::Isometry3d::Identity();
  /// Inverse covariance over the tangent [rho; phi], symmetric positive semi-definite.
  core::Matrix6d information = core::Matrix6d::Identity();
  FactorKind kind = FactorKind::odometry;  ///< default odometry
};

/// A loop's identity: its two keys, the lower robot's first.
using LoopId = std::pair<core::PoseKey, core::PoseKey>;

/// The identity of an inter-robot loop factor (either orientation).
LoopId loopId(const Factor& loop);

/// Nodes with their current estimates T_world_node, factors, and the nodes held fixed.
///
/// A factor may name a node the graph does not hold (a neighbour's pose in a
/// robot's local view of a distributed graph); solvers skip such factors.
class PoseGraph {
 public:
  /// Adds node `key` at `T_world_node`; a node that exists gets the new estimate.
  void addNode(const core::PoseKey& key, const Eigen::Isometry3d& T_world_node);

  /// Appends a factor (its ends need not be nodes yet).
  void addFactor(const Factor& factor);

  /// True when `key` is a node.
  [[nodiscard]] bool hasNode(const core::PoseKey& key) const { return nodes_.contains(key); }

  /// The estimate of node `key`; throws core::Error when there is no such node.
  [[nodiscard]] const Eigen::Isometry3d& estimate(const core::PoseKey& key) const;

  /// Replaces the estimate of node `key`; throws core::Error when there is no such node.
  void setEstimate(const core::PoseKey& key, const Eigen::Isometry3d& T_world_node);

  /// Holds node `key` fixed (the gauge); it need not be a node yet.
  void fix(const core::PoseKey& key) { fixed_.insert(key); }

  /// Lets node `key` move again.
  void unfix(const core::PoseKey& key) { fixed_.erase(key); }

  /// True when node `key` is held fixed.
  [[nodiscard]] bool isFixed(const core::PoseKey& key) const { return fixed_.contains(key); }

  /// Every node and its estimate T_world_node, by key (robot, then keyframe).
  [[nodiscard]] const std::map<core::PoseKey, Eigen::Isometry3d>& nodes() const { return nodes_; }

  /// Every factor, in the order added.
  [[nodiscard]] const std::vector<Factor>& factors() const { return factors_; }

  /// The fixed nodes.
  [[nodiscard]] const std::set<core::PoseKey>& fixedNodes() const { return fixed_; }

  /// The number of nodes.
  [[nodiscard]] std::size_t size() const { return nodes_.size(); }

  /// True when the factor's two ends are nodes of this graph.
  [[nodiscard]] bool connects(const Factor& factor) const;

 private:
  std::map<core::PoseKey, Eigen::Isometry3d> nodes_;
  std::vector<Factor> factors_;
  std::set<core::PoseKey> fixed_;
};

/// The residual of `factor` at the given estimates: log(T_from_to^-1 T_world_from^-1 T_world_to).
core::Vector6d factorResidual(const Factor& factor, const Eigen::Isometry3d& T_world_from,
                              const Eigen::Isometry3d& T_world_to);

/// g2o's chi-square of the graph: the sum of r^T Omega r over the factors whose
/// two ends are nodes (no robust loss).
double graphCost(const PoseGraph& graph);

/// The information matrix of a covariance: its inverse, with every eigenvalue
/// of the covariance raised to at least `min_variance` first, so a singular or
/// slightly indefinite covariance gives a finite, positive-definite information.
core::Matrix6d informationFromCovariance(const core::Matrix6d& covariance,
                                         double min_variance = 1e-9);

}  // namespace dcl::backend
