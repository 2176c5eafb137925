#pragma once

/// All robots of a dataset in one process over the simulated radio (DESIGN.md
/// §2 `swarm`), in lock-step simulated time. Each step: the radio moves to
/// the step's time (links follow the robots' true positions) and delivers;
/// then every robot, in parallel, takes in its messages and its scans of the
/// step; then what the robots sent goes to the radio in robot order. Robots
/// share nothing but the radio, and the radio sees the same sends in the same
/// order whatever the thread count, so a run is deterministic.

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
#include <dcl/robot/robot_node.hpp>

namespace dcl::swarm {

struct SwarmConfig {
  robot::RobotConfig robot;    ///< every robot's
  comm::SimRadioConfig radio;  ///< range, bandwidth, latency, losses
  double step =
      0.02;  ///< s of simulated time per step: scans play at their stamps, messages move every step
  double drain = 5.0;          ///< s the radio keeps running after the last scan
  std::size_t max_frames = 0;  ///< scans per robot at most (0: all)
  int threads = 0;             ///< robots processed at once (0: every core)
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
};

/// What a run leaves of one robot.
struct MemberResult {
  std::string name;
  std::size_t frames = 0;
  std::vector<core::Keyframe> keyframes;  ///< without their clouds
  backend::PoseGraph graph;               ///< robot::RobotNode::graph() at the end
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

/// Progress after each step: simulated time and every robot's frames done.
using SwarmProgress = std::function<void(double time, const std::vector<std::size_t>& frames)>;

/// Runs the members to the end of their scans and `drain` seconds more.
/// Throws core::Error for an invalid configuration or no member.
SwarmResult runSwarm(std::vector<SwarmMember> members, const SwarmConfig& config,
                     const SwarmProgress& progress = {});

}  // namespace dcl::swarm
