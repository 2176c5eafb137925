#pragma once

/// One robot's trajectory as PCM needs it (paper §III-C, Eq. 8): the
/// relative pose between two of its keyframes, z_{a_i a_j}, and that pose's
/// covariance, for many pairs of keyframes, cheaply.
///
/// The robot's odometry factors and intra-robot loops form a graph over its
/// keyframes. A breadth-first spanning tree of that graph from an origin
/// keyframe (fewest factors first, neighbours in keyframe order) fixes one
/// path between any two keyframes: up from the first to their lowest common
/// ancestor, down to the second. Each keyframe keeps its pose and covariance
/// composed from the origin along the tree, so a relative pose costs two
/// differences of cumulative values and an ancestor search (binary lifting,
/// O(log n)). With odometry alone the tree is the odometry chain.
///
/// Approximation: the relative pose is composed along that one path, first
/// order, with right perturbations (Sigma_{k+1} = Ad(Z^-1) Sigma_k Ad(Z^-1)^T
/// + Sigma_Z); the other paths (further loops) are not fused in, so the
/// covariance is an upper bound of the smoothed one. Through intra-robot loops
/// the path between two keyframes that are close in space but far apart in
/// time is short, which is what lets PCM tell a wrong inter-robot loop from a
/// right one on long trajectories; along the odometry chain alone their
/// covariance grows with the time between them.

#include <Eigen/Geometry>
#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <unordered_map>
#include <vector>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/ids.hpp>
#include <dcl/core/se3.hpp>

namespace dcl::backend {

/// A relative pose between two keyframes of one robot and its covariance
/// (right perturbation T exp(xi), tangent [rho; phi]).
struct RelativePose {
  Eigen::Isometry3d T_i_j = Eigen::Isometry3d::Identity();
  core::Matrix6d covariance = core::Matrix6d::Zero();
};

/// The covariance of a measurement with information `information`: its
/// inverse, every eigenvalue of the information raised to at least 1e-12
/// first, so that a direction the measurement says nothing about gets a large
/// but finite variance.
core::Matrix6d covarianceOf(const core::Matrix6d& information);

/// A robot's odometry and intra-robot loops as a spanning tree with cumulative
/// poses and covariances (see the file comment). Factors may arrive in any
/// order; the tree is rebuilt when it is next queried, and its numbers depend
/// only on the set of factors (of two factors between the same keyframes, the
/// first stays). Appending the next keyframe's odometry extends it in O(1)
/// without a rebuild. Not thread-safe (queries refresh the tree).
class TrajectoryTree {
 public:
  /// The tree of `robot` from keyframe `origin`; with `intra_loops` false, loop
  /// factors are ignored and the tree is the odometry chain.
  explicit TrajectoryTree(core::RobotId robot, core::KeyframeId origin = core::KeyframeId(0),
                          bool intra_loops = true);

  /// Adds an odometry factor (between consecutive keyframes, either direction)
  /// or an intra-robot loop of this robot. A factor between two keyframes that
  /// are joined already is ignored (the first one stays). Throws core::Error for
  /// another robot's factor, an inter-robot loop, or odometry between keyframes
  /// that are not consecutive.
  void add(const Factor& factor);

  /// True when keyframe `k` is connected to the origin.
  [[nodiscard]] bool reaches(core::KeyframeId k) const;

  /// The pose of keyframe `j` in the frame of keyframe `i` along the tree, and
  /// its covariance; throws core::Error when the tree does not reach both.
  [[nodiscard]] RelativePose relative(core::KeyframeId i, core::KeyframeId j) const;

  /// Counts the rebuilds that changed the path to a keyframe reached before, so
  /// that relative poses computed earlier may differ now.
  [[nodiscard]] std::uint64_t revision() const;

  /// The robot.
  [[nodiscard]] core::RobotId robot() const { return robot_; }

  /// Keyframes reached (the origin counts).
  [[nodiscard]] std::size_t size() const;

 private:
  static constexpr std::size_t kLevels = 32;  ///< binary-lifting levels: depths below 2^32
  struct Edge {
    Eigen::Isometry3d T;        ///< from this keyframe to the neighbour
    core::Matrix6d covariance;  ///< of T
  };
  struct Node {
    std::uint64_t keyframe = 0;
    std::uint64_t parent_keyframe = 0;  ///< the root's own keyframe for the root
    Eigen::Isometry3d T_origin_k = Eigen::Isometry3d::Identity();
    core::Matrix6d covariance = core::Matrix6d::Zero();  ///< of T_origin_k
    std::uint32_t depth = 0;
    std::array<std::uint32_t, kLevels> up{};  ///< ancestors 2^l levels up (the root: itself)
  };
  void refresh() const;
  void rebuild() const;
  void attach(std::uint64_t keyframe, std::uint32_t parent, const Edge& edge) const;
  [[nodiscard]] std::uint32_t lowestCommonAncestor(std::uint32_t u, std::uint32_t v) const;
  [[nodiscard]] RelativePose fromAncestor(std::uint32_t ancestor, std::uint32_t node) const;
  [[nodiscard]] std::uint32_t nodeOf(core::KeyframeId k) const;

  core::RobotId robot_;
  core::KeyframeId origin_;
  bool intra_loops_;
  /// The factor graph: neighbours of each keyframe, in keyframe order.
  std::map<std::uint64_t, std::map<std::uint64_t, Edge>> edges_;
  // The tree, rebuilt lazily by queries.
  mutable std::vector<Node> nodes_;
  mutable std::unordered_map<std::uint64_t, std::uint32_t> node_of_;
  mutable bool dirty_ = false;
  mutable std::uint64_t revision_ = 0;
};

}  // namespace dcl::backend
