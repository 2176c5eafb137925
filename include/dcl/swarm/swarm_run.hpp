#pragma once

/// All robots of a dataset in one process over the simulated radio (DESIGN.md
/// §2 `swarm`), in lock-step simulated time. Each step: the radio moves to
/// the step's time (links follow the robots' true positions) and delivers;
/// then every robot, in parallel, takes in its messages and its scans of the
/// step; then what the robots sent goes to the radio in robot order. Robots
/// share nothing but the radio, and the radio sees the same sends in the same
/// order whatever the thread count, so a run is deterministic. Each robot's
/// new keyframe clouds are kept, compact, for the map (merged_map.hpp), and a
/// progress callback sees every robot's figures after each step.

#include <Eigen/Geometry>
#include <cstddef>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <dcl/comm/sim_radio.hpp>
#include <dcl/core/keyframe.hpp>
#include <dcl/core/trajectory.hpp>
#include <dcl/io/scan_source.hpp>
#include <dcl/odometry/odometry.hpp>
#include <dcl/robot/robot_node.hpp>
#include <dcl/swarm/merged_map.hpp>

namespace dcl::swarm {

struct SwarmConfig {
  robot::RobotConfig robot;    ///< every robot's
  comm::SimRadioConfig radio;  ///< range, bandwidth, latency, losses
  double step =
      0.02;  ///< s of simulated time per step: scans play at their stamps, messages move every step
  double drain = 5.0;  ///< s the radio keeps running after the last scan
  /// s at most the run goes on past the drain while a robot still optimises
  /// (robot::RobotNode::settled): the loops of the last seconds get their round,
  /// and a round that ran out of steps its successors, as on robots left running.
  double settle = 60.0;
  std::size_t max_frames = 0;  ///< scans per robot at most (0: all)
  int threads = 0;             ///< robots processed at once (0: every core)
  MapConfig map;               ///< the keyframe clouds kept for the map (0: none)
};

/// One robot of the swarm: its scans, when it starts, and where it truly is
/// (for the radio's links; empty: it is always in range of everyone).
struct SwarmMember {
  std::string name;
  std::unique_ptr<io::ScanSource> scans;
  double start_time = 0.0;        ///< s on the swarm clock
  core::Trajectory ground_truth;  ///< T_world_sensor, stamps since its own start
  /// s on the swarm clock at which the robot leaves the swarm for good (a
  /// crash, a dead battery): from then on it takes no scan and says nothing.
  std::optional<double> leave_time;
  /// Its own front-end (e.g. odometry::ExternalOdometry); none: the built-in LiDAR odometry.
  std::unique_ptr<odometry::Odometry> front_end{};
};

/// What a run leaves of one robot.
struct MemberResult {
  std::string name;
  std::size_t frames = 0;
  std::vector<core::Keyframe> keyframes;  ///< without their clouds
  /// Their clouds for the map (none when SwarmConfig::map keeps no map).
  KeyframeClouds map_clouds;
  backend::PoseGraph graph;  ///< robot::RobotNode::graph() at the end, in `frame`
  /// The frame its estimates are in (robot/frames.hpp): the robot's own,
  /// joined by the loops between frames to the lowest frame they reach, so
  /// the robots of every group that ever met end in one; none when unknown.
  std::optional<core::RobotId> frame;
  std::vector<robot::InterLoop> inter_loops;
  std::map<std::string, double> counters;
  comm::RobotTraffic traffic;
  /// Bytes transmitted per message kind per meter interval (a broadcast once).
  std::map<comm::MessageKind, std::vector<std::size_t>> sent_over_time;
};

struct SwarmResult {
  std::vector<MemberResult> robots;
  double duration = 0.0;  ///< s of simulated time run
  std::size_t radio_events = 0;
};

/// One robot's figures while the run goes on.
struct RobotProgress {
  std::string name;
  std::size_t frames = 0;        ///< scans played
  std::size_t total_frames = 0;  ///< scans it will play
  std::size_t keyframes = 0;
  std::size_t inter_loops = 0;  ///< inter-robot loops PCM keeps now
  std::size_t bytes_sent = 0;   ///< bytes transmitted so far (a broadcast once)
  bool left = false;            ///< it has left the swarm
};

/// Where a run stands after a step.
struct SwarmStatus {
  double time = 0.0;                  ///< s of simulated time done
  double end = 0.0;                   ///< s of simulated time the run takes
  std::vector<RobotProgress> robots;  ///< in member order
  /// The robots themselves, in member order, to read (their estimates, for a
  /// live view) during the call only.
  std::vector<const robot::RobotNode*> nodes;
};

/// Called after each step, between the robots' parallel steps (nothing runs
/// meanwhile); it should return quickly, as it is called 50 times a simulated second.
using SwarmProgress = std::function<void(const SwarmStatus& status)>;

/// Runs the members to the end of their scans and `drain` seconds more.
/// Throws core::Error for an invalid configuration or no member.
SwarmResult runSwarm(std::vector<SwarmMember> members, const SwarmConfig& config,
                     const SwarmProgress& progress = {});

}  // namespace dcl::swarm
