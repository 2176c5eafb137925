// `dcl-slam play`: one robot's scans of a dataset published on a ROS 2 topic
// (sensor_msgs/PointCloud2, best effort) in real time, or faster with --rate,
// stamped with the wall clock as a LiDAR driver stamps them (or with their
// stamps in the dataset, as a bag player keeps the recorded ones): a robot's
// stream to try `robot --ros2`, RViz or Foxglove with, without a robot.
// With --epoch, the scans go out on a swarm's clock, as `robot` plays them:
// scan i of robot r at (start time of r + t_i) / rate after the epoch.
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <limits>
#include <string>
#include <thread>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/point_cloud2.hpp>
#include <dcl/ros/ros2_node.hpp>
#include <dcl/sim/imu_model.hpp>
#include <dcl/sim/sim_source.hpp>

#include "commands.hpp"
#include "option_checks.hpp"
#include "process.hpp"

namespace dcl::apps {
namespace {

struct PlayOptions {
  std::string dataset;
  std::string robot;
  std::optional<std::string> points;        ///< default: ros.points
  std::string odometry;                     ///< also the ground truth as nav_msgs/Odometry here
  std::string imu;                          ///< also the IMU's readings as sensor_msgs/Imu here
  std::optional<std::uint32_t> ros_domain;  ///< default: ros.domain
  std::optional<std::string> interface;     ///< default: ros.interface
  double rate = 1.0;                        ///< dataset seconds per wall second
  std::size_t max_frames = 0;               ///< 0: all
  double wait = 10.0;                       ///< s to wait for a subscriber before the first scan
  double epoch = 0.0;           ///< Unix time (s) of swarm time 0; 0: the first scan goes at once
  bool dataset_stamps = false;  ///< stamps from the dataset, not the wall clock
};

void runPlay(const PlayOptions& o, const AppConfig& config) {
  checkSwarmClock(o.epoch, o.rate);
  const StopSignals signals;
  const io::DatasetSpec spec = io::readDataset(o.dataset, datasetReadOptions());
  const auto index = spec.robotIndex(o.robot);
  if (!index) throw core::Error(fmt::format("dataset {} has no robot '{}'", o.dataset, o.robot));
  const auto scans = sim::openRobotScans(spec, *index);
  const std::size_t frames =
      o.max_frames > 0 ? std::min(o.max_frames, scans->size()) : scans->size();
  const std::string topic = named(o.points.value_or(config.ros.points), o.robot);
  const std::string frame = named(config.ros.sensor_frame, o.robot);
  ros2::Node node(ros2::NodeConfig{o.ros_domain.value_or(config.ros.domain),
                                   o.interface.value_or(config.ros.interface), "dcl_slam_play"});
  node.advertise<msg::PointCloud2>(topic, ros2::Qos::sensor_data);
  // A perfect front-end for trying the external odometry: the ground truth.
  const std::string odometry_topic = named(o.odometry, o.robot);
  const core::Trajectory truth =
      o.odometry.empty() ? core::Trajectory{} : io::readGroundTruth(spec, *index);
  if (!o.odometry.empty()) node.advertise<msg::Odometry>(odometry_topic, ros2::Qos::reliable);
  // The IMU's reading of up with each scan, as an orientation (the simulated
  // IMU sits at the LiDAR and reads roll and pitch to its model's accuracy).
  const std::string imu_topic = named(o.imu, o.robot);
  if (!o.imu.empty()) node.advertise<msg::Imu>(imu_topic, ros2::Qos::sensor_data);
  const double tilt_sigma = sim::ImuModel{}.readingSigma();
  // Best effort: scans sent before anyone listens are gone.
  const double wait_until = unixNow() + o.wait;
  while (stopSignal() == 0 && node.matched(topic) == 0 && unixNow() < wait_until)
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  fmt::print("play: {} scans of robot {} on {} ({} subscriber{}), rate {}\n", frames, o.robot,
             topic, node.matched(topic), node.matched(topic) == 1 ? "" : "s", o.rate);
  std::fflush(stdout);
  // Scan i is due at start + (t_i - first) / rate on the wall clock.
  const double start = o.epoch > 0.0 ? o.epoch : unixNow();
  const double first = o.epoch > 0.0 ? -spec.robots[*index].start_time
                       : frames > 0  ? scans->stamp(0)
                                     : 0.0;
  std::size_t sent = 0;
  for (std::size_t i = 0; i < frames && stopSignal() == 0; ++i) {
    const double due = start + (scans->stamp(i) - first) / o.rate;
    const double stamp = o.dataset_stamps ? scans->stamp(i) : due;
    while (stopSignal() == 0 && unixNow() < due)
      std::this_thread::sleep_for(std::chrono::duration<double>(std::min(0.05, due - unixNow())));
    if (!o.odometry.empty()) {
      if (const auto pose = truth.at(scans->stamp(i))) {
        msg::Odometry m;
        m.header = {stamp, named(config.ros.odom_frame, o.robot)};
        m.child_frame_id = named(config.ros.base_frame, o.robot);
        m.pose = *pose;
        node.publish(odometry_topic, m);
      }
    }
    if (!o.imu.empty()) {
      if (const auto up = scans->up(i))
        node.publish(imu_topic, msg::imuOfUp(*up, tilt_sigma * tilt_sigma, {stamp, frame}));
    }
    core::PointCloud scan = scans->scan(i);
    // Stamped with the wall clock when the scan is due, as a driver stamps it,
    // and played faster, the sweep is faster too (its points' times divided
    // by the rate), so that a front-end sees the motion the scans hold. With
    // the dataset's stamps, the sweep keeps its dataset time too.
    if (!o.dataset_stamps) {
      for (float& t : scan.time) t = static_cast<float>(t / o.rate);
    }
    node.publish(topic, msg::toPointCloud2(scan, {stamp, frame}));
    ++sent;
  }
  if (o.dataset_stamps)
    fmt::print("play: {} scans published in {:.1f} s; scan i stamped t_i, its dataset stamp\n",
               sent, unixNow() - start);
  else
    fmt::print(
        "play: {} scans published in {:.1f} s; scan i stamped {:.6f} + (t_i - {:.6f}) / {}\n", sent,
        unixNow() - start, start, first, o.rate);
  if (stopSignal() != 0) throw CLI::RuntimeError(128 + stopSignal());
}

}  // namespace

void addPlayCommand(CLI::App& app, const AppConfig& config) {
  auto o = std::make_shared<PlayOptions>();
  CLI::App* cmd = app.add_subcommand(
      "play",
      "publish one robot's scans of a dataset on ROS 2 (sensor_msgs/PointCloud2) in real time, "
      "as its LiDAR driver would: a stream for robot --ros2, RViz or Foxglove");
  cmd->add_option("--dataset", o->dataset, "dataset folder (dataset.yaml)")->required();
  cmd->add_option("--robot", o->robot, "the robot's name in the dataset")->required();
  cmd->add_option("--points", o->points, "topic (default: ros.points, {robot} replaced)");
  cmd->add_option("--odometry", o->odometry,
                  "also publish the robot's ground truth on this topic (nav_msgs/Odometry, before "
                  "each scan), a perfect front-end for robot --ros2 --odometry");
  cmd->add_option("--imu", o->imu,
                  "also publish the robot's IMU readings of up on this topic (sensor_msgs/Imu, "
                  "an orientation of that roll and pitch, before each scan), for robot --imu; "
                  "none for a dataset simulated --no-imu");
  cmd->add_option("--ros-domain", o->ros_domain, "DDS domain, ROS_DOMAIN_ID (default: ros.domain)")
      ->check(CLI::Range(0, 232));
  cmd->add_option("--interface", o->interface,
                  "network interface with multicast discovery, e.g. lo (default: ros.interface)");
  cmd->add_option("--rate", o->rate, "dataset seconds per wall second")->capture_default_str();
  cmd->add_option("--max-frames", o->max_frames, "scans to publish at most (0: all)")
      ->check(kNonNegative)
      ->capture_default_str();
  cmd->add_option("--wait", o->wait, "s to wait for a subscriber before the first scan")
      ->check(kNonNegative)
      ->capture_default_str();
  cmd->add_option("--epoch", o->epoch,
                  "Unix time (s) of swarm time 0: scan i goes out (start time + t_i) / rate after "
                  "it, as `robot` plays it (0: the first scan at once)")
      ->capture_default_str();
  cmd->add_flag("--dataset-stamps", o->dataset_stamps,
                "stamp each scan with its stamp in the dataset, as a bag player keeps the recorded "
                "stamps (default: the wall clock when it is due, as a driver stamps it)");
  cmd->callback([o, &config] { runPlay(*o, config); });
}

}  // namespace dcl::apps
