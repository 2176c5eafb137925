#pragma once

/// The joint pose graph of a multi-robot run: every robot's final graph
/// (its keyframes at the run's estimates, odometry, its own loops and the
/// inter-robot loops it holds) put together, with the ground truth at each
/// keyframe beside it. `bench bound` and `bench noise` evaluate it
/// (bound.hpp, factor_noise.hpp); the caller reads the run's files.

#include <Eigen/Geometry>
#include <cstddef>
#include <string>
#include <vector>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/ids.hpp>
#include <dcl/core/trajectory.hpp>

namespace dcl::eval {

/// One robot of a run: its keyframes' stamps and ground truth, and its graph.
struct RobotGraph {
  std::string name;
  core::RobotId id;
  std::vector<double> stamps;                 ///< per keyframe, keyframe k at index k
  std::vector<Eigen::Isometry3d> T_world_gt;  ///< ground truth at each keyframe
  core::Trajectory ground_truth;              ///< at any rate, associated by stamp
  /// Its own keyframes (nodes {id, k}) at the run's estimates, and every
  /// factor it holds, inter-robot loops included.
  backend::PoseGraph graph;
  /// It left the swarm mid-run: its estimates are those it held then.
  bool left = false;
};

/// What of the run's factors a joint graph holds.
enum class JointFactors {
  odometry,   ///< each robot's odometry
  own_loops,  ///< and its intra-robot loops
  joint,      ///< and the inter-robot loops, once each
  exact,      ///< the same with the inter-robot loops' measurements from the ground truth
};

/// The graph of the robots' own nodes, at the run's estimates, with
/// `factors`. Inter-robot loops to robots not in `robots` are left out. Each
/// robot's first keyframe is fixed when it has no inter-robot loop in the
/// graph, and the first robot's always.
backend::PoseGraph jointGraph(const std::vector<RobotGraph>& robots, JointFactors factors);

/// Per robot, the lowest robot (index into `robots`) its inter-robot loops
/// join it to, through any others: the robots whose maps the loops tie into one.
std::vector<std::size_t> loopGroups(const std::vector<RobotGraph>& robots);

}  // namespace dcl::eval
