#pragma once

/// How far the loops of a run could take its robots (`dcl-slam bench bound`,
/// and a table of `bench system`). The run's joint pose graph (run_graph.hpp)
/// is solved centrally, as it is and with every inter-robot loop's
/// measurement replaced by the ground truth. Beside the odometry, the robot's
/// own SLAM (odometry and its own loops) and the run, this tells whether a
/// robot's ATE is limited by the distributed solve, by the loops' accuracy,
/// or by where the robots drove: a robot whose route others barely share
/// gains little even from exact loops, and may lose (its neighbours' drift
/// comes in with them).

#include <cstddef>
#include <string>
#include <vector>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/eval/run_graph.hpp>

namespace dcl::eval {

/// ATE RMSE (m, each robot aligned on its own by SE(3), as the run's metrics)
/// of one robot's keyframes.
struct RobotBound {
  std::string name;
  double odometry = 0.0;   ///< its odometry alone
  double own_loops = 0.0;  ///< its odometry and its own loops, solved (single-robot SLAM)
  double run = 0.0;        ///< the run's final estimate
  double optimum = 0.0;    ///< the run's joint graph, solved centrally
  double exact = 0.0;      ///< the same with every inter-robot loop exact
  /// The same three under one SE(3) alignment for all robots its loops join
  /// it to, through any others, together (the merged map's consistency, the
  /// run's `ate_rmse_joint`): NaN when they share too few poses with the
  /// ground truth to align them.
  double run_joint = 0.0;
  double optimum_joint = 0.0;
  double exact_joint = 0.0;
  /// The robot left the swarm mid-run (RobotGraph::left).
  bool left = false;
};

/// The chi-square of the run's joint graph (odometry, own loops, each
/// inter-robot loop once; no robust loss) at the robots' final estimates, each
/// robot's own keyframes where it left them, and at the optimum. Their ratio
/// is how far the distributed solve stopped from the optimum.
///
/// When robots left mid-run, the same over the robots that stayed (their
/// factors and the loops between them): a robot that left keeps the
/// estimates it held then, and loops to it that no round took in before it
/// left cannot be reconciled by anyone, so the joint figure mixes what the
/// rest could not fix with how consistent they left their own maps.
struct JointCosts {
  double run = 0.0;
  double optimum = 0.0;
  std::vector<std::string> left;  ///< the robots that left, in id order
  double stayed_run = 0.0;
  double stayed_optimum = 0.0;
};

/// The joint graph of `robots` with `factors`, solved centrally (200
/// Levenberg-Marquardt iterations at most) from the run's estimates and from
/// the chordal initialisation: a run whose robots ended in frames of
/// different rounds is a poor start, and Levenberg-Marquardt can settle in a
/// local minimum from it. The solution of lower cost.
backend::PoseGraph solveJointGraph(const std::vector<RobotGraph>& robots, JointFactors factors);

/// The ATE RMSE (m, SE(3) alignment of this robot alone, as the run's
/// metrics) of robot `r`'s keyframes at their estimates in `graph`; NaN
/// when they cannot be aligned (a robot that has not moved yet).
double robotAte(const RobotGraph& r, const backend::PoseGraph& graph);

/// Every robot's ATE RMSE (m) in `graph` under one SE(3) alignment fitted on
/// the pairs of all robots of its loop group (loopGroups) together, as the
/// run's report measures `ate_rmse_joint` over the robots of one frame; NaN
/// for a group whose alignment cannot be fitted.
std::vector<double> jointAtes(const std::vector<RobotGraph>& robots,
                              const backend::PoseGraph& graph);

/// The bound of a run's robots, and the joint graph's costs into `costs`
/// when given (`RobotGraph::left` says which robots left).
std::vector<RobotBound> computeBound(const std::vector<RobotGraph>& robots,
                                     JointCosts* costs = nullptr);

/// The mean over the robots of 1 - value / base: the ATE lowered against
/// `base` (robots without either figure left out).
double meanLowered(const std::vector<RobotBound>& robots, double RobotBound::*value,
                   double RobotBound::*base);

/// The robots whose `value` is not below `base` (robots without either not counted).
std::size_t notBelow(const std::vector<RobotBound>& robots, double RobotBound::*value,
                     double RobotBound::*base);

}  // namespace dcl::eval
