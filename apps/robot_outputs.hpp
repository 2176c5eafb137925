#pragma once

// What `dcl-slam robot` leaves in its output folder and `dcl-slam swarm`
// reads back (cmd_robot.cpp, cmd_swarm.cpp): the files `dcl-slam run` writes
// per robot, plus robot.json, the process's own account of its run. One
// definition of robot.json on both sides keeps writer and reader in step.

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/comm/messenger.hpp>
#include <dcl/core/ids.hpp>
#include <dcl/core/trajectory.hpp>
#include <dcl/eval/run_report.hpp>

namespace dcl::apps {

/// One robot's entry of metrics.json, as `run` and `swarm` write it: its
/// counts, ATE and ARE with and without collaboration, bytes and rates. The
/// caller appends what only it knows, then the counters.
nlohmann::ordered_json robotMetricsJson(const eval::RobotRun& run, const eval::RobotMetrics& m);

/// When metrics.json's robots end in more than one frame (no loop joins
/// them), prints a line naming the robots of each: a merged map per frame.
void printFrames(const nlohmann::ordered_json& metrics);

/// The default incarnation of a robot process: tenths of a second since
/// 2024-01-01 00:00 UTC. A restart takes far longer than 0.1 s (joining DDS
/// alone does), so each life of a robot gets a larger number than the last,
/// and the count fits uint32 until August 2037. Throws core::Error for a
/// clock outside that span.
std::uint32_t clockIncarnation();

/// The account of one robot process, robot.json in its folder.
struct RobotReport {
  std::string name;        ///< the robot's name in the dataset
  std::uint8_t robot = 0;  ///< its id: its index in the dataset
  std::string dataset;     ///< the dataset folder
  std::string transport;   ///< "dds"
  std::string swarm;       ///< the swarm name (DDS partition)
  std::uint32_t incarnation = 0;
  double rate = 1.0;               ///< swarm seconds per wall second
  double epoch = 0.0;              ///< s since the Unix epoch at swarm time 0
  std::size_t frames = 0;          ///< scans played
  std::size_t frames_planned = 0;  ///< scans it was to play (--max-frames or all)
  std::size_t keyframes = 0;
  /// s of swarm time the latest scan was fed after it was due: how far the
  /// process fell behind the swarm clock (it never skips a scan).
  double max_lag = 0.0;
  double wall_time = 0.0;  ///< s from joining the swarm to the end
  double duration = 0.0;  ///< s, the swarm clock at the end (the time the traffic is averaged over)
  bool interrupted = false;        ///< stopped by SIGINT or SIGTERM before its end
  std::size_t bytes_sent = 0;      ///< put on the network (a broadcast once)
  std::size_t bytes_received = 0;  ///< addressed to it, or broadcast, and taken in
  double transmit_kBps = 0.0;      ///< bytes_sent over duration
  double receive_kBps = 0.0;       ///< bytes_received over duration
  std::size_t failed_writes = 0;  ///< samples the transport could not hand on (DDS: a full history)
  double meter_interval = 1.0;    ///< s of swarm time per sent_over_time bin
  /// Bytes sent per message kind name per meter interval, from swarm time 0.
  std::map<std::string, std::vector<std::size_t>> sent_over_time;
  std::map<std::string, double> counters;  ///< robot::RobotNode::counters()
  /// Every inter-robot loop it knows, by keyframe ids (a keyframe's id is
  /// its row in the trajectory files), and PCM's last verdict.
  struct Loop {
    core::PoseKey from;
    core::PoseKey to;
    bool accepted = false;
  };
  std::vector<Loop> inter_loops;
  /// The robot whose frame trajectory.tum and graph.g2o are in (robot's
  /// frames.hpp); none when unknown. `dcl-slam swarm` puts every robot in
  /// the lowest frame the loops between frames join its own to.
  std::optional<std::uint8_t> frame;
  /// The Messenger's statistics (messengerJson), for diagnostics only.
  nlohmann::ordered_json messenger = nlohmann::ordered_json::object();
};

/// robot.json's content.
nlohmann::ordered_json toJson(const RobotReport& report);

/// The Messenger's counts per message kind and drop reason, by name.
nlohmann::ordered_json messengerJson(const comm::MessengerStats& stats);

/// A robot's outputs: its keyframes by the full system (in its group's
/// frame) and by odometry alone, its final graph, and its report.
struct RobotOutputs {
  core::Trajectory estimate;
  core::Trajectory odometry;
  backend::PoseGraph graph;  ///< the final graph: own keyframes, factors, neighbours' ends
  RobotReport report;
};

/// Writes `folder`/trajectory.tum, trajectory.kitti + times.txt, odometry.tum,
/// graph.g2o and, last, robot.json; each atomically, so an interrupted
/// process leaves whole files or none.
void writeRobotOutputs(const std::string& folder, const RobotOutputs& outputs);

/// Reads what writeRobotOutputs wrote (the graph is left empty). Throws
/// core::FileError naming the file (and robot.json's field) that is missing or
/// malformed.
RobotOutputs readRobotOutputs(const std::string& folder);

}  // namespace dcl::apps
