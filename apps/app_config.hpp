#pragma once

/// The configuration of the whole program: one section per module, each with
/// a default on every field, filled from YAML by `--config FILE`.
/// `dcl-slam config --dump` prints it.

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <dcl/backend/dgs.hpp>
#include <dcl/backend/distributed_refine.hpp>
#include <dcl/backend/loop_check.hpp>
#include <dcl/backend/pcm.hpp>
#include <dcl/comm/dds_transport.hpp>
#include <dcl/comm/messenger.hpp>
#include <dcl/comm/sim_radio.hpp>
#include <dcl/odometry/external_odometry.hpp>
#include <dcl/odometry/lidar_odometry.hpp>
#include <dcl/odometry/local_mapper.hpp>
#include <dcl/place/descriptor.hpp>
#include <dcl/place/evaluation.hpp>
#include <dcl/registration/verification.hpp>
#include <dcl/robot/robot_node.hpp>
#include <dcl/swarm/merged_map.hpp>

namespace dcl::apps {

/// Trajectory evaluation defaults (`eval ate`, `eval rpe`, and runs that report ATE).
struct EvalSection {
  /// The largest RPE pair distance (frames or metres): far beyond any sequence.
  static constexpr double kMaxRpeDelta = 1e9;

  double max_time_diff = 0.01;  ///< s, largest stamp difference for associating poses (evo: 0.01)
  double time_offset = 0.0;     ///< s, added to the estimate's stamps before association
  std::string alignment = "none";         ///< none | se3 | sim3 (evo's default: none)
  double rpe_delta = 1.0;                 ///< RPE pair distance, in rpe_delta_unit
  std::string rpe_delta_unit = "frames";  ///< frames | meters
  /// KITTI odometry metric segment lengths, metres (the devkit's 100..800).
  std::vector<double> kitti_lengths{100, 200, 300, 400, 500, 600, 700, 800};
  int kitti_step = 10;  ///< frames between KITTI segment starts (the devkit's 10)

  template <class Visitor>
  void visit(Visitor& v) {
    v.field("max_time_diff", max_time_diff, "s, largest stamp difference to associate poses")
        .nonNegative();
    v.field("time_offset", time_offset, "s, added to the estimate's stamps before association")
        .finite();
    v.field("alignment", alignment, "none | se3 | sim3").oneOf({"none", "se3", "sim3"});
    v.field("rpe_delta", rpe_delta, "RPE pair distance, in rpe_delta_unit")
        .within(0.0, kMaxRpeDelta, core::Interval::open_low);
    v.field("rpe_delta_unit", rpe_delta_unit, "frames | meters").oneOf({"frames", "meters"});
    v.check(rpe_delta_unit != "frames" || (rpe_delta >= 1.0 && std::floor(rpe_delta) == rpe_delta),
            "rpe_delta", "must be a whole number of frames when rpe_delta_unit is frames",
            "rpe_delta_unit");
    v.field("kitti_lengths", kitti_lengths, "m, KITTI metric segment lengths")
        .rule(std::ranges::all_of(kitti_lengths,
                                  [](double l) { return l > 0.0 && std::isfinite(l); }),
              "must hold positive finite lengths");
    v.field("kitti_step", kitti_step, "frames between KITTI metric segment starts").positive();
  }
};

/// Place recognition: the descriptor, and how `bench place` searches and scores.
struct PlaceSection {
  place::DescriptorConfig descriptor;  ///< LiDAR-Iris or Scan Context and their parameters
  place::EvaluationConfig evaluation;  ///< true-loop distance, index (candidates, threshold)

  template <class Visitor>
  void visit(Visitor& v) {
    v.section("descriptor", descriptor, "the place descriptor (bench place: --descriptor wins)");
    v.section("evaluation", evaluation, "place-recognition evaluation and index");
  }
};

/// A robot node's own timers (robot::RobotConfig's fields outside the modules' sections).
struct RobotSection {
  double optimise_period = 20.0;  ///< s from the start of one optimisation round to the next
  double round_timeout = 30.0;    ///< s a round may go without a step before it is given up
  double announce_period = 2.0;   ///< s between announcements of the robot's loop neighbours
  /// Refinement steps after DGS in each optimisation round at most (the
  /// `refine` section's other fields apply; 0: DGS alone).
  int refine_steps = 200;
  /// DGS steps per stage at most in each optimisation round (the `dgs`
  /// section's caps are for whole offline graphs): the refinement goes on from
  /// wherever DGS stopped, and a round must end while the group is together.
  int dgs_steps = 100;
  int candidate_spacing = 3;  ///< own keyframes between two candidates to one neighbour, at least
  double loop_sigma_translation = 0.02;  ///< m, added to every verified loop's covariance
  double loop_sigma_rotation = 0.0035;   ///< rad, likewise
  double loop_sigma_tilt = 0.0;  ///< rad, instead about the keyframe's x and y axes when larger
  bool solve_alone = true;  ///< with no one to optimise with, solve against the last round's values
  bool hold_absent =
      true;  ///< in a round, hold the loops to absent neighbours where they were left

  template <class Visitor>
  void visit(Visitor& v) {
    v.field("optimise_period", optimise_period,
            "s from the start of one optimisation round to the start of the next, at least")
        .positive();
    v.field("round_timeout", round_timeout, "s a round may go without a step before it is given up")
        .positive();
    v.field("announce_period", announce_period,
            "s between announcements of the robot's loop neighbours (how groups form)")
        .positive();
    v.field("refine_steps", refine_steps,
            "refinement steps after DGS in each optimisation round at most (0: DGS alone)")
        .nonNegative();
    v.field("dgs_steps", dgs_steps, "DGS steps per stage in each optimisation round at most")
        .positive();
    v.field("candidate_spacing", candidate_spacing,
            "own keyframes between two loop candidates sent to one neighbour, at least (1: all)")
        .positive();
    v.field("loop_sigma_translation", loop_sigma_translation,
            "m, noise added to every verified loop (the registration's covariance is optimistic)")
        .nonNegative();
    v.field("loop_sigma_rotation", loop_sigma_rotation, "rad, likewise").nonNegative();
    v.field("loop_sigma_tilt", loop_sigma_tilt,
            "rad, instead about the keyframe's x and y axes (roll, pitch) when larger")
        .nonNegative();
    v.field("solve_alone", solve_alone,
            "with no one in range to optimise with, solve the own graph against the "
            "neighbours' poses as the last round left them");
    v.field("hold_absent", hold_absent,
            "in a round, hold the loops to neighbours out of range where the last rounds "
            "left them (the swarm's maps stay aligned)");
  }
};

/// A live robot on ROS 2 or ROS 1 (`robot --ros2`, `--ros1`): where its scans
/// come from and what it publishes. "{robot}" in a name stands for the robot's name.
struct RosSection {
  std::uint32_t domain = 0;        ///< ROS 2: DDS domain (ROS_DOMAIN_ID)
  std::string interface {};        ///< ROS 2: network interface ('': default)
  std::string master_uri{};        ///< ROS 1: the master ('': ROS_MASTER_URI)
  double master_wait = 10.0;       ///< ROS 1: s to wait for the master
  std::string points = "/points";  ///< sensor_msgs/PointCloud2 in
  std::string odometry_in{};       ///< nav_msgs/Odometry of an external front-end (empty: built-in)
  double odometry_wait = 0.5;      ///< s a scan waits for the external odometry to reach it
  std::string imu{};               ///< sensor_msgs/Imu in (empty: none)
  std::vector<double> imu_rpy{0.0, 0.0,
                              0.0};         ///< deg, the IMU's roll, pitch, yaw in the LiDAR frame
  double imu_max_gap = 0.05;                ///< s from a scan's stamp to its IMU reading at most
  std::string map_frame = "map";            ///< the group's frame
  std::string odom_frame = "{robot}/odom";  ///< the robot's odometry frame
  std::string base_frame = "{robot}/base_link";      ///< the robot
  std::string sensor_frame = "{robot}/lidar";        ///< the LiDAR (clouds `play` publishes)
  std::string odometry_topic = "/{robot}/odometry";  ///< nav_msgs/Odometry out, each keyframe
  std::string path_topic = "/{robot}/path";          ///< nav_msgs/Path of the keyframes
  std::string map_topic = "/{robot}/local_map";      ///< sensor_msgs/PointCloud2, latest keyframes
  std::string loops_topic = "/{robot}/loops";        ///< visualization_msgs/MarkerArray
  double publish_period = 1.0;                       ///< s between paths, maps and markers
  int map_keyframes = 30;                            ///< keyframes in the local map
  double map_voxel = 0.4;                            ///< m, voxel edge of the local map
  std::string whole_map_topic = "/{robot}/map";      ///< sensor_msgs/PointCloud2, every keyframe
  double whole_map_period = 10.0;                    ///< s between whole maps
  double whole_map_voxel = 0.8;                      ///< m, voxel edge of the whole map

  template <class Visitor>
  void visit(Visitor& v) {
    v.field("domain", domain, "ROS 2: DDS domain of the topics (ROS_DOMAIN_ID)")
        .atMost(comm::DdsConfig::kMaxDomain);
    v.field("interface", interface,
            "ROS 2: network interface with multicast discovery (empty: default)")
        .rule(interface.size() <= comm::DdsConfig::kMaxInterfaceChars &&
                  comm::isPlainName(interface, "_-.:"),
              "must be empty or a network interface name");
    v.field("master_uri", master_uri,
            "ROS 1: the master, e.g. http://localhost:11311 (empty: ROS_MASTER_URI)")
        .rule(master_uri.empty() || (master_uri.starts_with("http://") && master_uri.size() <= 255),
              "must be empty or an http:// URI");
    v.field("master_wait", master_wait, "ROS 1: s to wait for the master at the start")
        .within(0.0, 3600.0);
    v.field("points", points, "sensor_msgs/PointCloud2 topic of the robot's LiDAR");
    v.field("odometry_in", odometry_in,
            "nav_msgs/Odometry topic of the robot's own front-end (empty: the built-in LiDAR "
            "odometry); the external section's T_body_sensor and noise apply");
    v.field("odometry_wait", odometry_wait,
            "s a scan waits for the external odometry to reach its stamp, then is dropped")
        .within(0.0, 60.0);
    v.field("imu", imu,
            "sensor_msgs/Imu topic of the robot's IMU (empty: none): the built-in odometry "
            "levels roll and pitch with its orientation (odometry.use_imu)");
    v.field("imu_rpy", imu_rpy,
            "deg, the IMU frame's roll, pitch and yaw in the LiDAR frame (x, y, z axes, "
            "fixed), as the calibration between the two gives it")
        .rule(imu_rpy.size() == 3 && std::all_of(imu_rpy.begin(), imu_rpy.end(),
                                                 [](double a) { return std::abs(a) <= 360.0; }),
              "must be three angles in deg, each within [-360, 360]");
    v.field("imu_max_gap", imu_max_gap,
            "s between a scan's stamp and the IMU reading nearest it at most, and s a scan "
            "waits for a reading at or after its stamp (else it goes unlevelled)")
        .within(0.0, 1.0);
    v.field("map_frame", map_frame, "frame id of the group's map");
    v.field("odom_frame", odom_frame, "frame id of the robot's odometry");
    v.field("base_frame", base_frame, "frame id of the robot");
    v.field("sensor_frame", sensor_frame, "frame id of the LiDAR (the clouds `play` publishes)");
    v.field("odometry_topic", odometry_topic, "nav_msgs/Odometry published at each keyframe");
    v.field("path_topic", path_topic, "nav_msgs/Path of the keyframes in the map frame");
    v.field("map_topic", map_topic, "sensor_msgs/PointCloud2 of the latest keyframes' points");
    v.field("loops_topic", loops_topic, "visualization_msgs/MarkerArray of the inter-robot loops");
    v.field("publish_period", publish_period, "s between paths, maps and loop markers")
        .within(0.05, 3600.0);
    v.field("map_keyframes", map_keyframes, "keyframes in the local map").within(1, 1000);
    v.field("map_voxel", map_voxel, "m, voxel edge of the local map").within(0.05, 10.0);
    v.field("whole_map_topic", whole_map_topic,
            "sensor_msgs/PointCloud2 of all the robot's keyframes in the group's frame: the "
            "group's robots' whole maps together are the group's merged map");
    v.field("whole_map_period", whole_map_period, "s between whole maps").within(0.05, 3600.0);
    v.field("whole_map_voxel", whole_map_voxel, "m, voxel edge of the whole map")
        .within(0.05, 10.0);
  }
};

/// `name` (a ros section's topic or frame) with each "{robot}" replaced by `robot`.
std::string named(std::string name, const std::string& robot);

/// Everything `dcl-slam` can be configured with.
struct AppConfig {
  std::string log_level = "info";                 ///< trace | debug | info | warn | error | off
  EvalSection eval;                               ///< trajectory evaluation
  odometry::OdometryConfig odometry;              ///< the built-in LiDAR odometry
  odometry::ExternalOdometryConfig external;      ///< poses from another front-end
  odometry::LocalMapperConfig mapper;             ///< keyframes, intra-robot loops, local graph
  PlaceSection place;                             ///< place recognition
  registration::VerificationConfig verification;  ///< geometric verification of loop candidates
  backend::DgsConfig dgs;                         ///< distributed pose-graph optimisation
  backend::RefineConfig refine;                   ///< distributed refinement after DGS
  backend::PcmConfig pcm;                         ///< inter-robot loop outlier rejection
  backend::LoopCheckConfig loop_check;            ///< after PCM: loops the group cannot explain
  comm::MessengerConfig messenger;                ///< neighbours, heartbeats, retransmission
  comm::SimRadioConfig radio;                     ///< the simulated radio of swarm runs
  comm::DdsConfig dds;                            ///< Cyclone DDS between robot processes
  RobotSection robot;                             ///< a robot node's timers
  swarm::MapConfig map;                           ///< the map of swarm runs
  RosSection ros;                                 ///< a live robot on ROS 2 or ROS 1

  template <class Visitor>
  void visit(Visitor& v) {
    v.field("log_level", log_level, "trace | debug | info | warn | error | off")
        .oneOf({"trace", "debug", "info", "warn", "error", "off"});
    v.section("eval", eval, "trajectory evaluation");
    v.section("odometry", odometry, "the built-in LiDAR odometry");
    v.section("external", external, "external odometry (poses from another front-end)");
    v.section("mapper", mapper, "keyframes, intra-robot loop closure, local pose graph");
    v.section("place", place, "place recognition");
    v.section("verification", verification, "geometric verification of loop candidates");
    v.section("dgs", dgs, "distributed Gauss-Seidel pose-graph optimisation");
    v.section("refine", refine, "distributed nonlinear refinement after DGS");
    v.section("pcm", pcm, "PCM outlier rejection of inter-robot loops");
    v.section("loop_check", loop_check,
              "after PCM: inter-robot loops the group's joint solution cannot explain");
    v.section("messenger", messenger, "neighbours, heartbeats and retransmission between robots");
    v.section("radio", radio, "the simulated radio of swarm runs in one process");
    v.section("dds", dds, "Cyclone DDS between robot processes");
    v.section("robot", robot, "a robot node's optimisation timers");
    v.section("map", map, "the map of swarm runs (map.ply)");
    v.section("ros", ros,
              "a live robot on ROS 2 or ROS 1 (robot --ros2, --ros1): topics, frames, rates");
  }
};

/// The shared data folder (KITTI ground truth, test data): the DCL_DATA_DIR
/// environment variable, else the folder configured at build time.
std::string defaultDataDir();

/// A robot node's configuration: the modules' sections and the robot's timers.
robot::RobotConfig robotConfig(const AppConfig& config);

/// Checks every rule of the configuration, as reading a file does (here for
/// what was set after it, such as --log-level); throws core::FileError naming
/// `source`, the dotted key, the rule and the value.
void validate(const AppConfig& config, const std::string& source);

}  // namespace dcl::apps
