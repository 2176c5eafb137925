#pragma once

/// A multi-robot run made from real ground truth for the eval suite: KITTI
/// 00's poses (the shared data folder) split into three robots as the paper
/// splits KITTI sequences, every 10th pose a keyframe, odometry and loops
/// measured with noise drawn from a known covariance, the way `bench bound`
/// and `bench noise` find a run after reading its files.

#include <Eigen/Geometry>
#include <cstddef>
#include <random>
#include <string>
#include <vector>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/eval/run_graph.hpp>

#include "test_support.hpp"

namespace dcl::eval::test {

/// How the run is measured.
struct KittiRunOptions {
  double odometry_sigma_m = 0.02;    ///< per axis, between consecutive keyframes
  double odometry_sigma_rad = 2e-3;  ///< per axis
  double loop_sigma_m = 0.05;        ///< per axis, own and inter-robot loops
  double loop_sigma_rad = 5e-3;      ///< per axis
  /// The factors' covariances over the covariance their noise is drawn from
  /// (1: the noise model is right; above: too loose).
  double covariance_scale = 1.0;
  /// Every inter-robot loop's measurement is off by this much more (in the
  /// frame of its first keyframe): a consistent error no covariance explains.
  Eigen::Isometry3d inter_loop_bias = Eigen::Isometry3d::Identity();
  bool exact_loops = false;  ///< loops measure the true relative pose (their covariance stays)
  unsigned seed = 1;
};

inline constexpr std::size_t kKittiKeyframeStep = 10;   ///< frames a keyframe
inline constexpr std::size_t kKittiRobotFrames = 1200;  ///< frames of robots a and b; c: the rest
inline constexpr double kKittiLoopDistance = 3.0;       ///< m, keyframes closer are loops
inline constexpr std::size_t kKittiOwnLoopGap = 100;    ///< frames, own loops lie further apart

/// The factor of `T_a_b` measured with noise drawn from diag(sigma_m^2 x3,
/// sigma_rad^2 x3), right-perturbed as the solvers' residual measures it (none
/// when `noisy` is false), its information that of `covariance_scale` times
/// that covariance.
inline backend::Factor measure(const core::PoseKey& from, const core::PoseKey& to,
                               const Eigen::Isometry3d& T_a_b, double sigma_m, double sigma_rad,
                               bool noisy, const KittiRunOptions& o, std::mt19937& random) {
  std::normal_distribution<double> gaussian;
  core::Vector6d sigma;
  sigma << sigma_m, sigma_m, sigma_m, sigma_rad, sigma_rad, sigma_rad;
  core::Vector6d xi;
  for (int k = 0; k < 6; ++k) xi(k) = sigma(k) * gaussian(random);
  backend::Factor f;
  f.from = from;
  f.to = to;
  f.T_from_to = noisy ? T_a_b * core::expSE3(xi) : T_a_b;
  f.information = (o.covariance_scale * sigma.cwiseAbs2()).cwiseInverse().asDiagonal();
  return f;
}

/// Robot `r` of KITTI 00 split in three: its share of the ground truth, a
/// keyframe every kKittiKeyframeStep frames, its odometry, and its estimates:
/// the odometry compounded from its first ground truth pose.
inline RobotGraph kittiRobot(const core::Trajectory& gt, std::size_t r, const KittiRunOptions& o,
                             std::mt19937& random) {
  RobotGraph robot;
  robot.name = std::string(1, static_cast<char>('a' + r));
  robot.id = core::RobotId(static_cast<std::uint8_t>(r));
  const std::size_t first = r * kKittiRobotFrames;
  const std::size_t end = r == 2 ? gt.size() : first + kKittiRobotFrames;
  for (std::size_t i = first; i < end; ++i) robot.ground_truth.push_back(gt.stamp(i), gt.pose(i));
  for (std::size_t i = first; i < end; i += kKittiKeyframeStep) {
    robot.stamps.push_back(gt.stamp(i));
    robot.T_world_gt.push_back(gt.pose(i));
  }
  Eigen::Isometry3d T_world_estimate = robot.T_world_gt.front();
  robot.graph.addNode({robot.id, core::KeyframeId(0)}, T_world_estimate);
  for (std::size_t k = 1; k < robot.stamps.size(); ++k) {
    const backend::Factor f =
        measure({robot.id, core::KeyframeId(k - 1)}, {robot.id, core::KeyframeId(k)},
                robot.T_world_gt[k - 1].inverse() * robot.T_world_gt[k], o.odometry_sigma_m,
                o.odometry_sigma_rad, true, o, random);
    T_world_estimate = T_world_estimate * f.T_from_to;
    robot.graph.addNode({robot.id, core::KeyframeId(k)}, T_world_estimate);
    robot.graph.addFactor(f);
  }
  return robot;
}

/// The loops between robots a and b (a == b: own loops): keyframes closer
/// than kKittiLoopDistance (of one robot, more than kKittiOwnLoopGap frames
/// apart), into both robots' graphs.
inline void addLoops(std::vector<RobotGraph>& robots, std::size_t a, std::size_t b,
                     const KittiRunOptions& o, std::mt19937& random) {
  for (std::size_t i = 0; i < robots[a].stamps.size(); ++i) {
    for (std::size_t j = a == b ? i + 1 : 0; j < robots[b].stamps.size(); ++j) {
      const Eigen::Isometry3d& T_world_i = robots[a].T_world_gt[i];
      const Eigen::Isometry3d& T_world_j = robots[b].T_world_gt[j];
      if ((T_world_i.translation() - T_world_j.translation()).norm() >= kKittiLoopDistance)
        continue;
      if (a == b && robots[a].stamps[j] - robots[a].stamps[i] <= kKittiOwnLoopGap) continue;
      backend::Factor f =
          measure({robots[a].id, core::KeyframeId(i)}, {robots[b].id, core::KeyframeId(j)},
                  T_world_i.inverse() * T_world_j, o.loop_sigma_m, o.loop_sigma_rad, !o.exact_loops,
                  o, random);
      f.kind = a == b ? backend::FactorKind::intra_loop : backend::FactorKind::inter_loop;
      if (a != b) f.T_from_to = o.inter_loop_bias * f.T_from_to;
      robots[a].graph.addFactor(f);
      if (a != b) robots[b].graph.addFactor(f);
    }
  }
}

/// KITTI 00 as three robots a, b, c (frames 0-1199, 1200-2399, 2400-4540)
/// with their loops: every robot holds its odometry, its own loops, and every
/// inter-robot loop it is part of (both robots of a loop hold it, as their
/// graph.g2o files do).
inline std::vector<RobotGraph> kittiRun(const KittiRunOptions& o = {}) {
  const core::Trajectory gt = readKitti(evoData("KITTI_00_gt.txt"));
  std::mt19937 random(o.seed);
  std::vector<RobotGraph> robots;
  for (std::size_t r = 0; r < 3; ++r) robots.push_back(kittiRobot(gt, r, o, random));
  for (std::size_t a = 0; a < robots.size(); ++a)
    for (std::size_t b = a; b < robots.size(); ++b) addLoops(robots, a, b, o, random);
  return robots;
}

/// How many factors of each kind the robots' graphs hold together, each
/// inter-robot loop once.
struct FactorCount {
  std::size_t odometry = 0;
  std::size_t own_loops = 0;
  std::size_t inter_loops = 0;
};

inline FactorCount countFactors(const std::vector<RobotGraph>& robots) {
  FactorCount n;
  for (const RobotGraph& r : robots) {
    for (const backend::Factor& f : r.graph.factors()) {
      if (f.kind == backend::FactorKind::odometry) ++n.odometry;
      if (f.kind == backend::FactorKind::intra_loop) ++n.own_loops;
      // Held by both robots: counted by the lower one.
      if (f.kind == backend::FactorKind::inter_loop && std::min(f.from.robot, f.to.robot) == r.id)
        ++n.inter_loops;
    }
  }
  return n;
}

}  // namespace dcl::eval::test
