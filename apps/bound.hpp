#pragma once

/// How far the loops of a run could take its robots (`dcl-slam bench bound`,
/// and a table of `bench system`). The run's joint pose graph (every robot's
/// graph.g2o: its keyframes at their final estimates, odometry, intra- and
/// inter-robot loops) is solved centrally, as it is and with every
/// inter-robot loop's measurement replaced by the ground truth. Beside the
/// odometry, the robot's own SLAM (odometry and its own loops) and the run,
/// this tells whether a robot's ATE is limited by the distributed solve, by
/// the loops' accuracy, or by where the robots drove: a robot whose route
/// others barely share gains little even from exact loops, and may lose (its
/// neighbours' drift comes in with them).
///
/// `dcl-slam bench noise` reads the same outputs and sets the factors'
/// covariances beside their errors against the ground truth (odometry
/// compounded over spans of keyframes, own and inter-robot loops): whether the
/// noise model weighs odometry and loops as their errors do.

#include <cstddef>
#include <string>
#include <vector>

namespace dcl::apps {

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
  /// The robot left the swarm mid-run (`left_at_s` in the run's metrics.json).
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

/// The bound of the run in folder `run` (outputs of `dcl-slam run`) of the
/// dataset in folder `dataset`, and the joint graph's costs into `costs` when
/// given. Throws core::Error naming the file for a missing or inconsistent output.
std::vector<RobotBound> computeBound(const std::string& run, const std::string& dataset,
                                     JointCosts* costs = nullptr);

/// The mean over the robots of 1 - value / base: the ATE lowered against
/// `base` (robots without either figure left out).
double meanLowered(const std::vector<RobotBound>& robots, double RobotBound::*value,
                   double RobotBound::*base);

/// The robots whose `value` is not below `base` (robots without either not counted).
std::size_t notBelow(const std::vector<RobotBound>& robots, double RobotBound::*value,
                     double RobotBound::*base);

}  // namespace dcl::apps
