// `dcl-slam robot`: one robot of a dataset in this process, over Cyclone DDS.
// It plays its scans on the swarm clock, which every process of the swarm
// derives from the same epoch and rate, so that robots started separately
// (by `dcl-slam swarm`, or by hand on several machines) meet as in the
// dataset. It never skips a scan: a process that falls behind catches up as
// fast as it can and reports how late it got. After its last scan it lingers
// so that the exchanges and optimisation rounds under way with its peers can
// finish, and on while its peers still map or it still optimises with them
// (--settle at most), then writes the outputs `dcl-slam
// run` writes per robot, and robot.json (robot_outputs.hpp).
#include <algorithm>
#include <cctype>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <ratio>
#include <span>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include <dcl/comm/dds_transport.hpp>
#include <dcl/core/error.hpp>
#include <dcl/core/progress.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/point_cloud2.hpp>
#include <dcl/odometry/external_odometry.hpp>
#include <dcl/registration/voxel_filter.hpp>
#include <dcl/robot/robot_node.hpp>
#include <dcl/ros/imu_readings.hpp>
#include <dcl/ros/ros1_node.hpp>
#include <dcl/ros/ros2_node.hpp>
#include <dcl/sim/sim_source.hpp>

#include "commands.hpp"
#include "front_end.hpp"
#include "live_view.hpp"
#include "option_checks.hpp"
#include "output_folder.hpp"
#include "process.hpp"
#include "robot_outputs.hpp"
#include "run_swarm.hpp"

namespace dcl::apps {
namespace {

using WallClock = std::chrono::system_clock;

/// s of wall time between two ticks while nothing is due: messages are
/// handled within this (the DDS waitset wakes the loop sooner when a sample
/// arrives), and a signal is noticed within it.
constexpr double kTickPeriod = 0.005;

/// The transports a robot process can use (only one so far).
constexpr const char* kTransports = "dds";

struct RobotOptions {
  std::string dataset;
  std::string robot;
  std::string out = "out/robot";
  bool force = false;  ///< replace OUT/ROBOT even when it holds files no dcl-slam command wrote
  std::string transport = "dds";
  double rate = 1.0;            ///< swarm seconds per wall second
  double epoch = 0.0;           ///< s since the Unix epoch at swarm time 0; 0: now
  double linger = 10.0;         ///< s of swarm time after the last scan
  double settle = 60.0;         ///< s more at most while the robot still optimises
  std::size_t max_frames = 0;   ///< scans at most, 0: all
  double meter_interval = 1.0;  ///< s of swarm time per traffic bin (the radio section's)
  comm::DdsConfig dds;
  bool json = false;
  // Live on ROS 2 or ROS 1 instead of a dataset:
  bool ros2 = false;                  ///< scans from a ROS 2 topic
  bool ros1 = false;                  ///< scans from a ROS 1 topic
  std::optional<int> id;              ///< the robot's id in the swarm (0..254), live only
  std::optional<std::string> points;  ///< the cloud topic (default: ros.points)
  std::optional<std::string>
      odometry_in;                 ///< an external front-end's topic (default: ros.odometry_in)
  std::optional<std::string> imu;  ///< sensor_msgs/Imu topic (default: ros.imu)
  std::optional<std::uint32_t> ros_domain;  ///< ROS 2; default: ros.domain
  std::optional<std::string> ros_master;    ///< ROS 1; default: ros.master_uri, ROS_MASTER_URI
  std::vector<std::string> frame_ids;       ///< map, odom, base, sensor; default: the ros section's
  VizOptions viz;                           ///< served live to Foxglove

  [[nodiscard]] bool live() const { return ros2 || ros1; }
};

// ---- time --------------------------------------------------------------------------

/// The clock every process of a swarm shares: (wall clock - epoch) * rate.
struct SwarmClock {
  double epoch = 0.0;  ///< s since the Unix epoch
  double rate = 1.0;

  [[nodiscard]] double now() const { return (unixNow() - epoch) * rate; }
  /// Wall milliseconds from swarm time `from` to `to` (0 when `to` has passed).
  [[nodiscard]] std::chrono::milliseconds wallUntil(double from, double to) const {
    const double ms = std::ceil(std::max(0.0, to - from) / rate * 1000.0);
    return std::chrono::milliseconds(static_cast<std::int64_t>(ms));
  }
};

/// The live view (--viz), if any, with this robot as it stands.
void showLive(LiveView* view, const robot::RobotNode& node, const std::string& name, double time,
              std::size_t frames, std::size_t total_frames, std::size_t bytes_sent) {
  if (view == nullptr || !view->due()) return;
  swarm::SwarmStatus status;
  status.time = time;
  swarm::RobotProgress p;
  p.name = name;
  p.frames = frames;
  p.total_frames = total_frames;
  p.keyframes = node.keyframes().size();
  const auto loops = node.counters().find("inter_loops_accepted");
  p.inter_loops = loops == node.counters().end() ? 0 : static_cast<std::size_t>(loops->second);
  p.bytes_sent = bytes_sent;
  status.robots = {p};
  status.nodes = {&node};
  view->update(status);
}

// ---- the metered transport ------------------------------------------------------------

/// DdsTransport with its bytes counted. DDS keeps no byte counts, and the
/// report needs what this robot put on the network (a broadcast once, as the
/// simulated radio counts it) and what reached it, per kind over time.
class MeteredTransport final : public comm::Transport {
 public:
  MeteredTransport(comm::DdsTransport& dds, double interval) : dds_(&dds), interval_(interval) {}

  [[nodiscard]] core::RobotId self() const override { return dds_->self(); }

  void send(std::optional<core::RobotId> to, comm::MessageKind kind,
            std::span<const std::uint8_t> bytes) override {
    sent_ += bytes.size();
    const auto bin = static_cast<std::size_t>(std::max(0.0, now_) / interval_);
    std::vector<std::size_t>& series = over_time_[std::string(comm::name(kind))];
    if (series.size() <= bin) series.resize(bin + 1, 0);
    series[bin] += bytes.size();
    dds_->send(to, kind, bytes);
  }

  std::vector<comm::Datagram> receive() override {
    std::vector<comm::Datagram> in = dds_->receive();
    for (const comm::Datagram& d : in) received_ += d.bytes.size();
    return in;
  }

  /// The swarm time sends are binned at from now on.
  void setTime(double now) { now_ = now; }

  [[nodiscard]] std::size_t sent() const { return sent_; }
  [[nodiscard]] std::size_t received() const { return received_; }
  [[nodiscard]] const std::map<std::string, std::vector<std::size_t>>& overTime() const {
    return over_time_;
  }

 private:
  comm::DdsTransport* dds_;
  double interval_;
  double now_ = 0.0;
  std::size_t sent_ = 0;
  std::size_t received_ = 0;
  std::map<std::string, std::vector<std::size_t>> over_time_;
};

// ---- the run ------------------------------------------------------------------------------

void validate(const RobotOptions& o) {
  if (o.transport != "dds")
    throw core::Error(fmt::format("unknown transport '{}' (known: {})", o.transport, kTransports));
  checkSwarmClock(o.epoch, o.rate);
  if (!(o.linger >= 0.0) || !std::isfinite(o.linger))
    throw core::Error("--linger must be a finite number >= 0");
  if (!(o.settle >= 0.0) || !std::isfinite(o.settle))
    throw core::Error("--settle must be a finite number >= 0");
  try {
    comm::validate(o.dds);
  } catch (const core::Error& e) {
    throw core::Error(std::string(e.what()) +
                      " (from --domain, --swarm, --interface or the config's dds section)");
  }
}

/// The dataset index of robot `name`; the error lists the robots there are.
std::size_t robotIndex(const io::DatasetSpec& spec, const std::string& name) {
  if (const auto index = spec.robotIndex(name)) return *index;
  std::string known;
  for (const io::RobotSpec& r : spec.robots) known += (known.empty() ? "" : ", ") + r.name;
  throw core::Error(
      fmt::format("dataset {} has no robot '{}' (robots: {})", spec.folder, name, known));
}

/// What a robot process writes, from its node and transport: trajectories,
/// graph, and the report's traffic, counters and loops (the caller adds how
/// its scans came).
RobotOutputs nodeOutputs(const robot::RobotNode& node, const MeteredTransport& metered,
                         const comm::DdsTransport& dds, const RobotOptions& o, double duration) {
  RobotOutputs out;
  for (const core::Keyframe& k : node.keyframes()) {
    out.estimate.push_back(k.stamp, node.estimate(k.id));
    out.odometry.push_back(k.stamp, k.T_odom_keyframe);
  }
  out.graph = node.graph();
  RobotReport& r = out.report;
  r.name = o.robot;
  r.transport = o.transport;
  r.swarm = o.dds.swarm;
  r.keyframes = node.keyframes().size();
  r.duration = duration;
  r.bytes_sent = metered.sent();
  r.bytes_received = metered.received();
  const auto kBps = [&](std::size_t bytes) {
    return r.duration > 0.0 ? static_cast<double>(bytes) / 1000.0 / r.duration : 0.0;
  };
  r.transmit_kBps = kBps(r.bytes_sent);
  r.receive_kBps = kBps(r.bytes_received);
  r.failed_writes = dds.failedWrites();
  r.meter_interval = o.meter_interval;
  r.sent_over_time = metered.overTime();
  r.counters = node.counters();
  for (const robot::InterLoop& loop : node.interLoops())
    r.inter_loops.push_back({loop.factor.from, loop.factor.to, loop.accepted});
  r.messenger = messengerJson(node.messenger().stats());
  if (const std::optional<core::RobotId> frame = node.frame()) r.frame = frame->value();
  return out;
}

/// One robot process's life, from joining the swarm to its outputs.
struct RobotPlayer {
  const RobotOptions& o;
  io::DatasetSpec spec;
  std::size_t index;
  std::unique_ptr<io::ScanSource> scans;
  std::size_t frames;
  SwarmClock clock;
  std::uint32_t incarnation;
  comm::DdsTransport dds;
  MeteredTransport metered;
  robot::RobotNode node;
  std::size_t next = 0;                                   ///< the next scan
  double max_lag = 0.0;                                   ///< s of swarm time
  double joined_at = 0.0;                                 ///< s since the Unix epoch
  double now = -std::numeric_limits<double>::infinity();  ///< the swarm clock at the last look
  LiveView* view = nullptr;                               ///< --viz

  RobotPlayer(const RobotOptions& options, io::DatasetSpec dataset, std::size_t robot,
              const robot::RobotConfig& config, const odometry::ExternalOdometryConfig& external)
      : o(options),
        spec(std::move(dataset)),
        index(robot),
        scans(sim::openRobotScans(spec, index)),
        frames(o.max_frames > 0 ? std::min(o.max_frames, scans->size()) : scans->size()),
        clock{o.epoch > 0.0 ? o.epoch : unixNow(), o.rate},
        incarnation(clockIncarnation()),
        dds(core::RobotId(static_cast<std::uint8_t>(index)), o.dds),
        metered(dds, o.meter_interval),
        node(metered, config, incarnation,
             datasetFrontEnd(spec, index, *scans, o.max_frames, external)),
        joined_at(unixNow()) {}

  /// s on the swarm clock at which scan `i` is due.
  [[nodiscard]] double due(std::size_t i) const {
    return spec.robots[index].start_time + scans->stamp(i);
  }

  /// The swarm clock, never going back (the wall clock may be stepped; the
  /// node's timers need a non-decreasing time).
  double look() {
    now = std::max(now, clock.now());
    metered.setTime(now);
    return now;
  }

  void tick() {
    node.tick(look());
    showLive(view, node, o.robot, now, next, frames, metered.sent());
  }

  /// Waits for the epoch without ticking: the swarm clock starts at 0.
  void waitForEpoch() {
    while (stopSignal() == 0 && look() < 0.0)
      std::this_thread::sleep_for(
          std::min(clock.wallUntil(now, 0.0), std::chrono::milliseconds(100)));
  }

  void feed() {
    max_lag = std::max(max_lag, look() - due(next));
    node.addScan(scans->stamp(next), scans->scan(next), scans->up(next));
    ++next;
  }

  /// Sleeps until `until` (swarm time), a sample arrives, or a tick is due.
  void sleep(double until) {
    const auto tick = std::chrono::milliseconds(static_cast<std::int64_t>(kTickPeriod * 1000.0));
    dds.wait(std::min(clock.wallUntil(now, until), tick));
  }

  std::string note() const {
    const auto& c = node.counters();
    const auto count = [&](const char* name) {
      const auto it = c.find(name);
      return it == c.end() ? 0.0 : it->second;
    };
    return fmt::format("t = {:.0f} s, {} keyframes, {} inter loops kept, lag {:.1f} s", now,
                       node.keyframes().size(), count("inter_loops_accepted"), max_lag);
  }

  /// Plays the scans and lingers; returns false when a signal cut it short.
  bool run() {
    core::ProgressBar progress("robot " + o.robot, frames, "frames");
    waitForEpoch();
    double end = std::numeric_limits<double>::infinity();
    while (stopSignal() == 0) {
      if (next < frames && due(next) <= look()) {
        feed();  // late scans one after the other, with a tick between them
        tick();
        if (progress.enabled()) progress.update(next, note());
        continue;
      }
      if (next == frames && !std::isfinite(end)) end = now + o.linger;
      // Lingering: on while a peer still maps (its places may yet match this
      // robot's) or a round is due, for --settle s more at most.
      const bool peers_done = now >= node.peersMappedAt() + o.linger;
      if (now >= end && ((peers_done && node.settled()) || now >= end + o.settle)) break;
      tick();
      if (progress.enabled()) progress.update(next, note());
      sleep(next < frames ? std::min(due(next), end) : std::max(end, now));
    }
    progress.finish();
    node.stop();  // a round still refining keeps the last step its group kept
    return stopSignal() == 0;
  }

  [[nodiscard]] RobotOutputs outputs(bool interrupted) const {
    RobotOutputs out = nodeOutputs(node, metered, dds, o, std::max(0.0, now));
    RobotReport& r = out.report;
    r.robot = static_cast<std::uint8_t>(index);
    r.dataset = o.dataset;
    r.rate = clock.rate;
    r.epoch = clock.epoch;
    r.frames = next;
    r.frames_planned = frames;
    r.max_lag = max_lag;
    r.wall_time = unixNow() - joined_at;
    r.interrupted = interrupted;
    r.incarnation = incarnation;
    return out;
  }
};

// ---- live, on ROS 2 or ROS 1 ----------------------------------------------------------

/// ROS 2 for a live robot: a DDS participant in the ros section's domain.
struct Ros2Middleware {
  using Node = ros2::Node;
  using Qos = ros2::Qos;
  static constexpr const char* kName = "ROS 2";

  static ros2::NodeConfig nodeConfig(const RosSection& ros, const std::string& robot) {
    return {ros.domain, ros.interface, "dcl_slam_" + robot};
  }
  static void checkTopic(const std::string& topic) { (void)ros2::ddsTopicName(topic); }
  static std::string where(const RosSection& ros) {
    return fmt::format("ROS 2 domain {}", ros.domain);
  }
};

/// ROS 1 for a live robot: a roscpp node named dcl_slam_ROBOT.
struct Ros1Middleware {
  using Node = ros1::Node;
  using Qos = ros1::Qos;
  static constexpr const char* kName = "ROS 1";

  static ros1::NodeConfig nodeConfig(const RosSection& ros, const std::string& robot) {
    return {"dcl_slam_" + robot, ros.master_uri, ros.master_wait};
  }
  static void checkTopic(const std::string& topic) { ros1::checkTopicName(topic); }
  static std::string where(const RosSection& ros) {
    return ros.master_uri.empty() ? std::string("ROS 1 (ROS_MASTER_URI)")
                                  : fmt::format("ROS 1 master {}", ros.master_uri);
  }
};

/// A robot fed by its LiDAR driver over ROS 2 or ROS 1 (Middleware), publishing
/// what it estimates while it runs, with the same swarm traffic as a robot
/// playing a dataset. Scans that arrive while the front-end is busy are dropped
/// and counted (the newest waits, never a queue); it runs until SIGINT or SIGTERM.
template <class Middleware>
struct LiveRobot {
  using Node = typename Middleware::Node;
  using Qos = typename Middleware::Qos;

  const RobotOptions& o;
  RosSection ros;  ///< names resolved for this robot
  std::uint8_t id;
  Node ros_node;
  std::uint32_t incarnation;
  comm::DdsTransport dds;
  MeteredTransport metered;
  odometry::ExternalOdometry* external = nullptr;  ///< the node's front-end, when external
  robot::RobotNode node;
  double joined_at;                                       ///< s since the Unix epoch
  double now = -std::numeric_limits<double>::infinity();  ///< s since joining
  std::optional<double> stamp_offset;  ///< s from a ROS stamp to the node's clock
  /// The newest scan not yet taken: its stamp on the node's clock, the scan,
  /// and when it arrived (s since the Unix epoch).
  struct Waiting {
    double stamp = 0.0;
    core::PointCloud scan;
    double arrived = 0.0;
    bool held_for_imu = false;  ///< taken but for its IMU reading, still on its way
  };
  std::optional<Waiting> waiting;
  /// The IMU's readings of up in the LiDAR frame (ros.imu), by stamp on the
  /// node's clock, the last kImuWindow seconds of them (longer than a scan
  /// waits behind a busy front-end; 4,000 readings of a 400 Hz IMU).
  static constexpr double kImuWindow = 10.0;
  Eigen::Matrix3d R_lidar_imu;
  msg::UpReadings imu_readings;
  std::size_t imu_received = 0;  ///< IMU messages
  /// While no IMU reading has come yet, for this long after the first scan
  /// (s), a scan still waits for its reading: the IMU's topic is a
  /// connection of its own, and its first reading may come a moment after the
  /// scan of the same stamp. Later, scans wait only while the IMU talks.
  static constexpr double kImuFirstReadingWait = 1.0;
  std::optional<double> first_scan_arrived;  ///< on the wall clock
  std::size_t imu_without_orientation = 0;   ///< of them, no orientation to level with
  std::size_t scans_without_imu = 0;         ///< scans with no IMU reading within ros.imu_max_gap
  std::size_t without_odometry = 0;          ///< scans the external odometry did not reach in time
  std::size_t odometry_received = 0;         ///< external odometry messages
  std::size_t odometry_refused = 0;          ///< of them, not after the last one, or not finite
  std::size_t received = 0;                  ///< clouds that arrived
  std::size_t dropped = 0;  ///< of them, replaced by a newer one before the front-end took them
  std::size_t refused = 0;  ///< of them, unreadable (no x, y, z; sizes that do not fit)
  std::string last_refusal;
  std::size_t frames = 0;  ///< scans through the front-end
  std::size_t published_keyframes = 0;
  double next_publish = 0.0;
  double next_whole_map = 0.0;
  LiveView* view = nullptr;  ///< --viz

  LiveRobot(const RobotOptions& options, const AppConfig& app, std::uint8_t robot)
      : o(options),
        ros(resolved(app.ros, options)),
        id(robot),
        ros_node(checkedTopics(ros, Middleware::nodeConfig(ros, options.robot))),
        incarnation(clockIncarnation()),
        dds(core::RobotId(robot), o.dds),
        metered(dds, o.meter_interval),
        node(metered, robotConfig(app), incarnation, frontEnd(ros, app.external, external)),
        joined_at(unixNow()),
        R_lidar_imu(msg::rotationOfRpy(ros.imu_rpy.at(0), ros.imu_rpy.at(1), ros.imu_rpy.at(2))) {}

  /// `config` once every topic name is one the middleware takes (a bad name
  /// fails before the node joins).
  template <class Config>
  static Config checkedTopics(const RosSection& ros, Config config) {
    for (const std::string* topic :
         {&ros.points, &ros.odometry_topic, &ros.path_topic, &ros.map_topic, &ros.loops_topic,
          &ros.odometry_in, &ros.whole_map_topic, &ros.imu}) {
      if (!topic->empty()) Middleware::checkTopic(*topic);
    }
    return config;
  }

  /// An external front-end fed from ros.odometry_in, or none (the built-in odometry).
  static std::unique_ptr<odometry::Odometry> frontEnd(const RosSection& ros,
                                                      const odometry::ExternalOdometryConfig& c,
                                                      odometry::ExternalOdometry*& raw) {
    if (ros.odometry_in.empty()) return nullptr;
    auto front_end =
        std::make_unique<odometry::ExternalOdometry>(odometry::ExternalOdometry::streaming(c));
    raw = front_end.get();
    return front_end;
  }

  static RosSection resolved(RosSection s, const RobotOptions& o) {
    if (o.points) s.points = *o.points;
    if (o.odometry_in) s.odometry_in = *o.odometry_in;
    if (o.imu) s.imu = *o.imu;
    if (o.ros_domain) s.domain = *o.ros_domain;
    if (o.ros_master) s.master_uri = *o.ros_master;
    if (o.frame_ids.size() == 4) {
      s.map_frame = o.frame_ids[0];
      s.odom_frame = o.frame_ids[1];
      s.base_frame = o.frame_ids[2];
      s.sensor_frame = o.frame_ids[3];
    }
    if (s.interface.empty()) s.interface = o.dds.interface;  // one network for both, unless told
    for (std::string* name :
         {&s.points, &s.odometry_in, &s.imu, &s.map_frame, &s.odom_frame, &s.base_frame,
          &s.odometry_topic, &s.path_topic, &s.map_topic, &s.loops_topic, &s.whole_map_topic}) {
      *name = named(*name, o.robot);
    }
    return s;
  }

  double look() {
    now = std::max(now, unixNow() - joined_at);
    metered.setTime(now);
    return now;
  }

  /// `stamp` (a ROS stamp) on the node's clock; the first message sets the offset.
  double nodeStamp(double stamp) {
    if (!stamp_offset) stamp_offset = look() - stamp;
    return stamp + *stamp_offset;
  }

  void onCloud(msg::PointCloud2&& m) {
    ++received;
    core::PointCloud cloud;
    try {
      cloud = io::decodePointCloud2(m.view(), m.header.stamp, /*drop_nan=*/true);
    } catch (const core::Error& e) {
      ++refused;
      last_refusal = e.what();
      return;
    }
    // A scan held only for its IMU reading goes now, without waiting longer:
    // the next scan is here, and the reading was not.
    if (waiting && waiting->held_for_imu) takeWaiting(/*newer_scan=*/true);
    if (waiting) ++dropped;
    if (!first_scan_arrived) first_scan_arrived = unixNow();
    waiting = Waiting{nodeStamp(m.header.stamp), std::move(cloud), unixNow()};
  }

  void onImu(msg::Imu&& m) {
    ++imu_received;
    const double stamp = nodeStamp(m.header.stamp);
    if (!imu_readings.add(m, R_lidar_imu, stamp - m.header.stamp)) {
      if (++imu_without_orientation == 1) {
        spdlog::warn(
            "robot {}: the IMU on {} sends no orientation (orientation_covariance[0] = -1): its "
            "readings level nothing; an orientation filter (e.g. imu_filter_madgwick) or the "
            "driver's own gives one",
            o.robot, ros.imu);
      }
      return;
    }
    imu_readings.dropBefore(stamp - kImuWindow);
  }

  void onOdometry(msg::Odometry&& m) {
    ++odometry_received;
    if (!external->append(nodeStamp(m.header.stamp), m.pose)) ++odometry_refused;
  }

  /// The waiting scan through the front-end when it can go: at once with the
  /// built-in odometry, once the external one reaches its stamp otherwise
  /// (dropped and counted after ros.odometry_wait).
  void takeWaiting(bool newer_scan = false) {
    if (!waiting) return;
    if (external != nullptr && !external->reaches(waiting->stamp)) {
      if (unixNow() - waiting->arrived > ros.odometry_wait) {
        ++without_odometry;
        waiting.reset();
      }
      return;
    }
    // Its IMU reading may still be on its way (another connection): the scan
    // waits for a reading at or after its stamp, ros.imu_max_gap at most,
    // and only while the IMU talks at all (or may yet say its first word).
    const bool imu_talks =
        imu_received > 0 ||
        (first_scan_arrived && unixNow() - *first_scan_arrived < kImuFirstReadingWait);
    waiting->held_for_imu = !newer_scan && !ros.imu.empty() && imu_talks &&
                            !imu_readings.reaches(waiting->stamp) &&
                            unixNow() - waiting->arrived < ros.imu_max_gap;
    if (waiting->held_for_imu) return;
    std::optional<Eigen::Vector3d> up;
    if (!ros.imu.empty()) {
      up = imu_readings.nearest(waiting->stamp, ros.imu_max_gap);
      if (!up && ++scans_without_imu == 1) {
        if (imu_readings.newest()) {
          spdlog::warn(
              "robot {}: no reading on {} within {} s of the scan stamped {:.3f} s (the newest at "
              "{:.3f} s, {} held): are the IMU and the LiDAR stamped on one clock?",
              o.robot, ros.imu, ros.imu_max_gap, rosStamp(waiting->stamp),
              rosStamp(*imu_readings.newest()), imu_readings.size());
        } else {
          spdlog::warn("robot {}: no reading on {} yet: scans go unlevelled until one comes",
                       o.robot, ros.imu);
        }
      }
    }
    node.addScan(waiting->stamp, waiting->scan, up);
    waiting.reset();
    ++frames;
  }

  /// A keyframe's time as its scan was stamped.
  [[nodiscard]] double rosStamp(double stamp) const { return stamp - stamp_offset.value_or(0.0); }

  void publishKeyframe() {
    const auto& keyframes = node.keyframes();
    if (keyframes.size() == published_keyframes) return;
    published_keyframes = keyframes.size();
    const core::Keyframe& k = keyframes.back();
    const Eigen::Isometry3d T_map_base = node.estimate(k.id);
    const double stamp = rosStamp(k.stamp);
    msg::Odometry odometry;
    odometry.header = {stamp, ros.map_frame};
    odometry.child_frame_id = ros.base_frame;
    odometry.pose = T_map_base;
    odometry.pose_covariance = k.covariance;
    ros_node.publish(ros.odometry_topic, odometry);
    msg::TFMessage tf;
    tf.transforms.resize(2);
    tf.transforms[0].header = {stamp, ros.map_frame};
    tf.transforms[0].child_frame_id = ros.odom_frame;
    tf.transforms[0].transform = T_map_base * k.T_odom_keyframe.inverse();
    tf.transforms[1].header = {stamp, ros.odom_frame};
    tf.transforms[1].child_frame_id = ros.base_frame;
    tf.transforms[1].transform = k.T_odom_keyframe;
    ros_node.publish("/tf", tf);
  }

  /// The points of keyframes `first`... at their estimates, one a voxel of edge `voxel`.
  [[nodiscard]] core::PointCloud mapOf(std::size_t first, double voxel) const {
    const auto& keyframes = node.keyframes();
    std::vector<Eigen::Vector3f> points;
    for (std::size_t i = first; i < keyframes.size(); ++i) {
      const Eigen::Isometry3f T = node.estimate(keyframes[i].id).cast<float>();
      for (const Eigen::Vector3f& p : keyframes[i].cloud.points) points.push_back(T * p);
    }
    core::PointCloud map;
    for (const Eigen::Vector3d& p : registration::voxelDownsample(points, voxel)) {
      map.points.push_back(p.cast<float>());
    }
    return map;
  }

  /// The path, local map and loop markers, every ros.publish_period, and the
  /// whole map every ros.whole_map_period (or all at once).
  void publishMaps(bool at_once = false) {
    const auto& keyframes = node.keyframes();
    if ((!at_once && look() < next_publish) || keyframes.empty()) return;
    next_publish = now + ros.publish_period;
    const double stamp = rosStamp(keyframes.back().stamp);
    msg::Path path;
    path.header = {stamp, ros.map_frame};
    for (const core::Keyframe& k : keyframes) {
      path.poses.push_back({{rosStamp(k.stamp), ros.map_frame}, node.estimate(k.id)});
    }
    ros_node.publish(ros.path_topic, path);

    const std::size_t first =
        keyframes.size() - std::min(keyframes.size(), static_cast<std::size_t>(ros.map_keyframes));
    ros_node.publish(ros.map_topic,
                     msg::toPointCloud2(mapOf(first, ros.map_voxel), {stamp, ros.map_frame}));
    // Every keyframe, at a lower rate: each robot's whole map in the group's
    // frame, the group's merged map together (no cloud crosses the radio for it).
    if (at_once || now >= next_whole_map) {
      next_whole_map = now + ros.whole_map_period;
      ros_node.publish(ros.whole_map_topic,
                       msg::toPointCloud2(mapOf(0, ros.whole_map_voxel), {stamp, ros.map_frame}));
    }

    // The accepted inter-robot loops, as lines between the two keyframes.
    const backend::PoseGraph graph = node.graph();
    msg::Marker lines;
    lines.header = {stamp, ros.map_frame};
    lines.ns = "inter_robot_loops";
    lines.type = msg::Marker::kLineList;
    lines.scale = {0.3, 0.0, 0.0};
    lines.color = {1.0F, 0.5F, 0.0F, 1.0F};
    for (const robot::InterLoop& loop : node.interLoops()) {
      if (!loop.accepted || !graph.hasNode(loop.factor.from) || !graph.hasNode(loop.factor.to)) {
        continue;
      }
      lines.points.push_back(graph.estimate(loop.factor.from).translation());
      lines.points.push_back(graph.estimate(loop.factor.to).translation());
    }
    msg::Marker clear;
    clear.header = lines.header;
    clear.action = msg::Marker::kDeleteAll;
    ros_node.publish(ros.loops_topic, msg::MarkerArray{{clear, lines}});
  }

  std::string note() const {
    return fmt::format("t = {:.0f} s, {} scans in, {} dropped, {} keyframes", now, received,
                       dropped, node.keyframes().size());
  }

  [[nodiscard]] RobotOutputs outputs() const {
    RobotOutputs out = nodeOutputs(node, metered, dds, o, std::max(0.0, now));
    // Trajectories stamped as the scans were (the driver's clock), not by the node's.
    for (core::Trajectory* t : {&out.estimate, &out.odometry}) {
      core::Trajectory stamped;
      for (std::size_t i = 0; i < t->size(); ++i)
        stamped.push_back(rosStamp(t->stamp(i)), t->pose(i));
      *t = std::move(stamped);
    }
    RobotReport& r = out.report;
    r.robot = id;
    r.dataset = std::string(Middleware::kName) + " " + ros.points;
    r.incarnation = incarnation;
    r.epoch = joined_at;
    r.frames = frames;
    r.frames_planned = received;
    r.wall_time = unixNow() - joined_at;
    r.interrupted = true;
    r.counters["scans_received"] = static_cast<double>(received);
    r.counters["scans_dropped"] = static_cast<double>(dropped);
    r.counters["scans_refused"] = static_cast<double>(refused);
    std::size_t messages_refused = 0;
    for (const auto& [topic, refusals] : ros_node.refused()) messages_refused += refusals.first;
    r.counters["messages_refused"] = static_cast<double>(messages_refused);
    if (!ros.imu.empty()) {
      r.counters["imu_received"] = static_cast<double>(imu_received);
      r.counters["imu_without_orientation"] = static_cast<double>(imu_without_orientation);
      r.counters["scans_without_imu"] = static_cast<double>(scans_without_imu);
    }
    if (external != nullptr) {
      r.counters["scans_without_odometry"] = static_cast<double>(without_odometry);
      r.counters["odometry_received"] = static_cast<double>(odometry_received);
      r.counters["odometry_refused"] = static_cast<double>(odometry_refused);
    }
    return out;
  }

  /// Runs until a signal; returns false (a live robot ends only when told to).
  bool run() {
    ros_node.template subscribe<msg::PointCloud2>(
        ros.points, Qos::sensor_data, [this](msg::PointCloud2&& m) { onCloud(std::move(m)); });
    if (external != nullptr) {
      // Best effort matches any writer; deep enough for a fast front-end's
      // poses between two scans' work.
      ros_node.template subscribe<msg::Odometry>(
          ros.odometry_in, Qos::sensor_data,
          [this](msg::Odometry&& m) { onOdometry(std::move(m)); }, 1000);
    }
    if (!ros.imu.empty()) {
      // Deep enough for a 400 Hz IMU between two scans' work.
      ros_node.template subscribe<msg::Imu>(
          ros.imu, Qos::sensor_data, [this](msg::Imu&& m) { onImu(std::move(m)); }, 1000);
    }
    ros_node.template advertise<msg::Odometry>(ros.odometry_topic, Qos::reliable);
    ros_node.template advertise<msg::TFMessage>("/tf", Qos::reliable);
    ros_node.template advertise<msg::Path>(ros.path_topic, Qos::transient_local);
    ros_node.template advertise<msg::PointCloud2>(ros.map_topic, Qos::transient_local);
    ros_node.template advertise<msg::PointCloud2>(ros.whole_map_topic, Qos::transient_local);
    ros_node.template advertise<msg::MarkerArray>(ros.loops_topic, Qos::transient_local);
    fmt::print("robot {}: reading {} on {}{}; publishing {}, {}, {}, {}, {} and /tf\n", o.robot,
               ros.points, Middleware::where(ros),
               ros.imu.empty() ? std::string() : ", its IMU on " + ros.imu, ros.odometry_topic,
               ros.path_topic, ros.map_topic, ros.whole_map_topic, ros.loops_topic);
    std::fflush(stdout);
    const auto tick = std::chrono::milliseconds(static_cast<std::int64_t>(kTickPeriod * 1000.0));
    while (stopSignal() == 0) {
      ros_node.spin(tick);
      takeWaiting();
      node.tick(look());
      showLive(view, node, o.robot, now, frames, received, metered.sent());
      publishKeyframe();
      publishMaps();
    }
    // Told to stop: the round with the peers under way, or the one the last
    // loops call for, ends first (a peer stopped at the same time does the
    // same), for --settle s at most; a second signal leaves at once.
    const double settle_until = look() + o.settle;
    if (!node.settled() && o.settle > 0.0) {
      fmt::print(
          "robot {}: finishing the round with its peers (at most {:g} s; signal again to "
          "leave now)\n",
          o.robot, o.settle);
      std::fflush(stdout);
    }
    while (stopSignalCount() < 2 && !node.settled() && look() < settle_until) {
      ros_node.spin(tick);
      node.tick(look());
      publishMaps();
    }
    node.stop();
    // The final estimates, as the outputs will hold them, and time for the
    // middleware's threads to send them before the node leaves.
    publishKeyframe();
    publishMaps(/*at_once=*/true);
    std::this_thread::sleep_for(std::chrono::milliseconds(300));
    return false;
  }
};

void printSummary(const RobotReport& r, const std::string& folder) {
  const auto count = [&](const char* name) {
    const auto it = r.counters.find(name);
    return it == r.counters.end() ? 0.0 : it->second;
  };
  fmt::print(
      "robot {}: {} of {} frames, {} keyframes, loops {} intra + {}/{} inter kept; sent {:.1f} kB "
      "({:.2f} kB/s), received {:.1f} kB ({:.2f} kB/s); max lag {:.2f} s; {:.1f} s wall{}\n",
      r.name, r.frames, r.frames_planned, r.keyframes, count("intra_loops"),
      count("inter_loops_accepted"), count("inter_loops_accepted") + count("inter_loops_rejected"),
      static_cast<double>(r.bytes_sent) / 1000.0, r.transmit_kBps,
      static_cast<double>(r.bytes_received) / 1000.0, r.receive_kBps, r.max_lag, r.wall_time,
      r.interrupted ? ", INTERRUPTED" : "");
  fmt::print("outputs in {}\n", folder);
}

/// A robot on ROS 2 or ROS 1: `robot --ros2 --robot NAME --id N` (or --ros1).
template <class Middleware>
void runLiveRobot(const RobotOptions& o, const AppConfig& config) {
  if (!o.id) {
    throw core::Error(fmt::format("robot --{}: give the robot's id in the swarm with --id (0..254)",
                                  o.ros1 ? "ros1" : "ros2"));
  }
  // The name is a folder of --out and part of topic and frame names.
  const bool plain = !o.robot.empty() && o.robot.size() <= 64 &&
                     std::all_of(o.robot.begin(), o.robot.end(), [](char c) {
                       return std::isalnum(static_cast<unsigned char>(c)) != 0 || c == '_';
                     });
  if (!plain) {
    throw core::Error(
        fmt::format("--robot '{}': a live robot's name is letters, digits and '_' "
                    "(it names its folder, topics and frames)",
                    o.robot));
  }
  const StopSignals signals;
  OutputFolder output(o.out + "/" + o.robot, o.force, {"robot.log", "play.log"});
  const std::unique_ptr<LiveView> view =
      o.viz.port ? std::make_unique<LiveView>(*o.viz.port, std::vector{o.robot}, o.viz.wait)
                 : nullptr;
  LiveRobot<Middleware> live(o, config, static_cast<std::uint8_t>(*o.id));
  live.view = view.get();
  live.run();
  const RobotOutputs outputs = live.outputs();
  writeRobotOutputs(output.path(), outputs);
  output.commit();
  if (o.json)
    fmt::print("{}\n", toJson(outputs.report).dump(2));
  else
    printSummary(outputs.report, output.out());
  std::fflush(stdout);
  if (live.refused > 0) {
    std::fprintf(stderr, "dcl-slam robot %s: %zu clouds on %s were unreadable (the last: %s)\n",
                 o.robot.c_str(), live.refused, live.ros.points.c_str(), live.last_refusal.c_str());
  }
  if (live.scans_without_imu > 0 || live.imu_without_orientation > 0) {
    std::fprintf(stderr,
                 "dcl-slam robot %s: %zu of %zu scans went unlevelled (no IMU reading on %s within "
                 "%g s); %zu of %zu IMU messages had no orientation\n",
                 o.robot.c_str(), live.scans_without_imu, live.frames, live.ros.imu.c_str(),
                 live.ros.imu_max_gap, live.imu_without_orientation, live.imu_received);
  }
  for (const auto& [topic, refusals] : live.ros_node.refused()) {
    std::fprintf(stderr, "dcl-slam robot %s: %zu messages on %s were refused (the last: %s)\n",
                 o.robot.c_str(), refusals.first, topic.c_str(), refusals.second.c_str());
  }
  std::fprintf(stderr, "dcl-slam robot %s: stopped by signal %d; outputs in %s\n", o.robot.c_str(),
               stopSignal(), output.out().c_str());
  throw CLI::RuntimeError(128 + stopSignal());
}

void runRobot(const RobotOptions& o, const AppConfig& config) {
  validate(o);
  if (o.ros2 && o.ros1) throw core::Error("robot: --ros2 or --ros1, not both");
  if (o.live()) {
    if (!o.dataset.empty()) {
      throw core::Error(
          fmt::format("robot: --dataset or --{}, not both", o.ros1 ? "ros1" : "ros2"));
    }
    if (o.ros1 && o.ros_domain) throw core::Error("robot: --ros-domain is for ROS 2 (--ros2)");
    if (o.ros2 && o.ros_master) throw core::Error("robot: --ros-master is for ROS 1 (--ros1)");
    for (const std::string& frame : o.frame_ids) {
      if (frame.empty() || frame.find_first_of(" \t\n,") != std::string::npos)
        throw core::Error(fmt::format("--frame-ids: '{}' is not a frame id", frame));
    }
    if (o.ros_master && !o.ros_master->starts_with("http://")) {
      throw core::Error(
          fmt::format("--ros-master '{}': a master's URI is http://HOST:PORT", *o.ros_master));
    }
    if (o.ros1)
      runLiveRobot<Ros1Middleware>(o, config);
    else
      runLiveRobot<Ros2Middleware>(o, config);
    return;
  }
  if (o.dataset.empty())
    throw core::Error("robot: --dataset is required (or --ros2 / --ros1 for a live robot)");
  if (o.id || o.points || o.ros_domain || o.odometry_in || o.imu || o.ros_master ||
      !o.frame_ids.empty())
    throw core::Error(
        "robot: --id, --points, --odometry, --ros-domain, --ros-master and --frame-ids are for a "
        "live robot (--ros2, --ros1)");
  const StopSignals signals;
  io::DatasetSpec spec = io::readDataset(o.dataset, datasetReadOptions());
  const std::size_t index = robotIndex(spec, o.robot);
  if (index > 254) throw core::Error("a swarm holds robots 0..254: '" + o.robot + "' is past it");
  // Staged beside OUT/ROBOT before the run (an unwritable place fails at once)
  // and put in place whole; the swarm's log of this process stays in it.
  OutputFolder output(o.out + "/" + o.robot, o.force, {"robot.log", "play.log"});
  const std::string& folder = output.out();
  // The viewer waited for before the robot's clock starts.
  const std::unique_ptr<LiveView> view =
      o.viz.port ? std::make_unique<LiveView>(*o.viz.port, std::vector{o.robot}, o.viz.wait)
                 : nullptr;
  RobotPlayer player(o, std::move(spec), index, robotConfig(config), config.external);
  player.view = view.get();
  const bool finished = player.run();
  const RobotOutputs outputs = player.outputs(!finished);
  writeRobotOutputs(output.path(), outputs);
  output.commit();
  if (o.json)
    fmt::print("{}\n", toJson(outputs.report).dump(2));
  else
    printSummary(outputs.report, folder);
  std::fflush(stdout);
  if (!finished) {
    std::fprintf(stderr, "dcl-slam robot %s: stopped by signal %d; outputs so far in %s\n",
                 o.robot.c_str(), stopSignal(), folder.c_str());
    throw CLI::RuntimeError(128 + stopSignal());
  }
}

}  // namespace

void addRobotCommand(CLI::App& app, const AppConfig& config) {
  auto o = std::make_shared<RobotOptions>();
  o->dds = config.dds;
  o->meter_interval = config.radio.meter_interval;
  CLI::App* cmd = app.add_subcommand(
      "robot",
      "one robot of a dataset in this process over Cyclone DDS: plays its scans on the swarm "
      "clock ((wall clock - epoch) * rate) with its peers in other processes, then writes its "
      "trajectories, graph and robot.json into OUT/ROBOT");
  cmd->add_option("--dataset", o->dataset, "dataset folder (dataset.yaml); or --ros2 / --ros1");
  cmd->add_option("--robot", o->robot, "the robot's name in the dataset")->required();
  cmd->add_option("--out", o->out, "output folder (the robot writes into OUT/ROBOT)")
      ->capture_default_str();
  cmd->add_option("--transport", o->transport, std::string("how robots talk: ") + kTransports)
      ->capture_default_str();
  cmd->add_option("--rate", o->rate, "swarm seconds per wall second (2: twice real time)")
      ->capture_default_str();
  cmd->add_option("--epoch", o->epoch,
                  "Unix time (s) of swarm time 0, the same for every robot of the swarm (0: now)")
      ->capture_default_str();
  cmd->add_option("--linger", o->linger,
                  "s of swarm time to keep running after the last scan (peers' exchanges and "
                  "optimisation rounds finish)")
      ->capture_default_str();
  cmd->add_option("--settle", o->settle,
                  "s of swarm time at most to keep running after --linger while peers still map "
                  "(--linger s after a peer's last keyframe) or rounds with them go on (their "
                  "last loops and unconverged rounds); live: s after Ctrl-C")
      ->capture_default_str();
  cmd->add_option("--max-frames", o->max_frames, "scans to play at most (0: all)")
      ->check(kNonNegative)
      ->capture_default_str();
  cmd->add_option("--swarm", o->dds.swarm, "swarm name, the DDS partition (default: dds.swarm)")
      ->capture_default_str();
  cmd->add_option("--domain", o->dds.domain, "DDS domain id (default: dds.domain)")
      ->capture_default_str();
  cmd->add_option("--interface", o->dds.interface,
                  "network interface with multicast discovery, e.g. lo (default: dds.interface)");
  cmd->add_flag("--json", o->json, "print robot.json at the end instead of the summary line");
  addForceFlag(*cmd, o->force);
  cmd->add_flag("--ros2", o->ros2,
                "live: scans from a ROS 2 topic (the config's ros section), estimates published "
                "on ROS 2 while it runs, until Ctrl-C");
  cmd->add_flag("--ros1", o->ros1,
                "live: the same on ROS 1, through roscpp (a master at ROS_MASTER_URI or "
                "--ros-master)");
  cmd->add_option("--id", o->id, "live: the robot's id in the swarm, 0..254, unique")
      ->check(CLI::Range(0, 254));
  cmd->add_option("--points", o->points,
                  "live: sensor_msgs/PointCloud2 topic (default: ros.points)");
  cmd->add_option("--odometry", o->odometry_in,
                  "live: nav_msgs/Odometry topic of the robot's own front-end, used instead of the "
                  "built-in odometry (default: ros.odometry_in)");
  cmd->add_option("--imu", o->imu,
                  "live: sensor_msgs/Imu topic of the robot's IMU, its orientation levelling the "
                  "built-in odometry's roll and pitch (default: ros.imu, none)");
  cmd->add_option("--ros-domain", o->ros_domain,
                  "live: DDS domain of the ROS 2 topics, ROS_DOMAIN_ID (default: ros.domain)")
      ->check(CLI::Range(0, 232));
  cmd->add_option("--frame-ids", o->frame_ids,
                  "live: MAP,ODOM,BASE,SENSOR frame ids ({robot} stands for the name; default: "
                  "the ros section's map_frame, odom_frame, base_frame, sensor_frame)")
      ->delimiter(',')
      ->expected(4);
  addVizOptions(*cmd, o->viz);
  cmd->add_option("--ros-master", o->ros_master,
                  "live: the ROS 1 master's URI (default: ros.master_uri, else ROS_MASTER_URI)");
  cmd->callback([o, &config] { runRobot(*o, config); });
}

}  // namespace dcl::apps
