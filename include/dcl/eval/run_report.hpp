#pragma once

/// The results of a swarm run, their metrics, and the report a user opens
/// (DESIGN.md §3): per robot ATE with and without collaboration, loops, bytes,
/// and a standalone HTML page of SVG plots. Nothing here knows how the run
/// was made (one process over the simulated radio, or one process per robot):
/// the runner fills a RunSummary.

#include <Eigen/Core>
#include <array>
#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <dcl/core/trajectory.hpp>

namespace dcl::eval {

/// One robot's side of a run.
struct RobotRun {
  std::string name;
  /// Keyframe poses T_world_sensor after the full system, in the common frame
  /// (the anchor's odometry frame; a robot that never met the anchor's group
  /// stays in its own odometry frame).
  core::Trajectory estimate;
  /// The same keyframes by the robot's odometry alone, in its own odometry frame.
  core::Trajectory odometry;
  /// The robot whose frame `estimate` is in: robots of one frame share the
  /// one alignment of `ate_rmse_joint`. Empty: one frame for all.
  std::string frame;
  /// Ground truth T_world_sensor at any rate (associated by stamp); empty when the dataset has
  /// none.
  core::Trajectory ground_truth;
  std::size_t frames = 0;
  std::size_t keyframes = 0;
  std::size_t intra_loops = 0;
  std::size_t inter_loops_accepted = 0;
  std::size_t inter_loops_rejected = 0;
  /// Of the accepted inter-robot loops this robot is the lower robot of, those
  /// the ground truth says are wrong (loopIsWrong); none without ground truth.
  std::optional<std::size_t> inter_loops_accepted_wrong;
  std::size_t bytes_sent = 0;
  std::size_t bytes_received = 0;
  /// Bytes sent per message kind name ("descriptor", ...) per time bin of
  /// RunSummary::meter_interval, from t = 0.
  std::map<std::string, std::vector<std::size_t>> sent_over_time;
  /// Every decision counted ("descriptors_sent", "candidates", "verified",
  /// "rejected_low_inlier_share", "pcm_rejected", "dgs_rounds", ...).
  std::map<std::string, double> counters;
};

/// An inter-robot loop as the report draws it.
struct RunLoop {
  std::size_t robot_a = 0;  ///< index into RunSummary::robots
  std::size_t robot_b = 0;
  Eigen::Vector3d p_a = Eigen::Vector3d::Zero();  ///< keyframe positions in the common frame
  Eigen::Vector3d p_b = Eigen::Vector3d::Zero();
  bool accepted = false;  ///< kept by PCM
};

struct RunSummary {
  std::string dataset;  ///< name or folder, for the title
  std::vector<RobotRun> robots;
  std::vector<RunLoop> loops;
  /// The merged map, for its picture from above: points in the common frame
  /// (as the robots' `estimate`) and the robot (index into `robots`) each
  /// comes from. Empty: the run kept no map.
  std::vector<Eigen::Vector3f> map_points;
  std::vector<std::uint8_t> map_robots;
  double meter_interval = 1.0;  ///< s, width of the traffic bins
  double duration = 0.0;        ///< s of data played
};

/// Metrics of one robot; ATE/ARE only when it has ground truth.
struct RobotMetrics {
  /// m, RMSE of the full system's keyframes, SE(3)-aligned per robot.
  std::optional<double> ate_rmse;
  /// m, RMSE of the odometry alone at the same keyframes, SE(3)-aligned per robot.
  std::optional<double> ate_rmse_odometry_only;
  /// m, RMSE of the full system with one SE(3) alignment for all robots in
  /// its frame (fitted on all their keyframes): how well the maps agree.
  std::optional<double> ate_rmse_joint;
  std::optional<double> are_rmse_deg;                ///< deg, as ate_rmse
  std::optional<double> are_rmse_deg_odometry_only;  ///< deg, as ate_rmse_odometry_only
  double transmit_kBps = 0.0;  ///< kB/s sent, averaged over the run's duration
  double receive_kBps = 0.0;   ///< kB/s received
};

/// The metrics of every robot, in RunSummary::robots' order.
std::vector<RobotMetrics> evaluateRun(const RunSummary& run);

/// A standalone HTML page (inline SVG and CSS, no scripts, no external
/// files): a table per robot (ATE with and without collaboration, loops,
/// bytes) and plots of the trajectories over ground truth seen from above
/// with the inter-robot loops drawn between them (accepted and rejected
/// apart), the merged map from above coloured by robot with the accepted
/// loops on it (an embedded PNG), ATE per robot with and without
/// collaboration, and traffic over time per message kind.
std::string reportHtml(const RunSummary& run, const std::vector<RobotMetrics>& metrics);

}  // namespace dcl::eval
