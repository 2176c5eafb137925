#pragma once

/// ROS 2 bags in MCAP, the format `ros2 bag record` writes by default:
/// `sensor_msgs/PointCloud2` scans, and trajectories from `nav_msgs/Odometry`
/// or `geometry_msgs/PoseStamped`, read and written without ROS 2. The file is
/// read by io::McapReader, the messages (CDR, schema encoding "ros2msg") by
/// the ROS 2 codec (ros2_messages.hpp); PointCloud2 points by
/// io::decodePointCloud2, as from a ROS1 bag.
///
/// Topic names match with or without their leading '/'. Type names match in
/// ROS 2's form ("sensor_msgs/msg/PointCloud2") or ROS 1's ("sensor_msgs/PointCloud2").

#include <Eigen/Geometry>
#include <cstddef>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include <dcl/core/point_cloud.hpp>
#include <dcl/core/trajectory.hpp>
#include <dcl/io/mcap.hpp>
#include <dcl/io/rosbag.hpp>
#include <dcl/io/scan_source.hpp>
#include <dcl/ros/messages.hpp>

namespace dcl::ros2 {

/// The message definition (schema data, encoding "ros2msg") ROS 2 bags carry
/// for `type` ("sensor_msgs/msg/PointCloud2", "nav_msgs/msg/Odometry" or
/// "geometry_msgs/msg/PoseStamped"): the message's .msg, then every type it
/// uses after a line of '=' and "MSG: pkg/Type". Throws core::Error for another type.
const std::string& messageDefinition(std::string_view type);

/// The topics of the MCAP file at `path`, sorted by name, each with its schema
/// name and message count. Throws core::FileError when it cannot be read.
std::vector<io::BagTopic> listMcapTopics(const std::string& path);

/// Streams the `sensor_msgs/PointCloud2` messages of one topic, in log-time
/// order. Errors are core::FileError naming the file, the topic and the message index.
class McapCloudReader {
 public:
  /// Opens `path` and selects `topic`; throws core::FileError when the file
  /// cannot be read, has no such topic, or the topic is not CDR PointCloud2.
  McapCloudReader(const std::string& path, const std::string& topic,
                  const io::BagCloudOptions& options = {});
  ~McapCloudReader();
  McapCloudReader(McapCloudReader&&) noexcept;
  McapCloudReader& operator=(McapCloudReader&&) noexcept;
  McapCloudReader(const McapCloudReader&) = delete;
  McapCloudReader& operator=(const McapCloudReader&) = delete;

  /// The next scan (stamped by its header); none after the last. Throws
  /// core::FileError on a damaged message, after moving past it.
  std::optional<io::StampedCloud> next();
  /// Number of messages on the topic.
  [[nodiscard]] std::size_t size() const;
  /// Number of messages read so far (the 0-based index of the next one).
  [[nodiscard]] std::size_t index() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Every scan of `topic` in `path` (see McapCloudReader).
std::vector<io::StampedCloud> readMcapClouds(const std::string& path, const std::string& topic,
                                             const io::BagCloudOptions& options = {});

/// The poses T_world_body of `topic` (nav_msgs/Odometry or geometry_msgs/PoseStamped),
/// stamped from their headers, in log-time order. Throws core::FileError naming
/// the file, the topic and the message index.
core::Trajectory readMcapTrajectory(const std::string& path, const std::string& topic);

/// The sensor_msgs/Imu messages of `topic`, in log-time order. Throws
/// core::FileError naming the file, the topic and the message index.
std::vector<msg::Imu> readMcapImu(const std::string& path, const std::string& topic);

/// The PointCloud2 messages of one MCAP topic as a robot's scans: stamps are the
/// header stamps relative to the first message's. Cheapest in order (an
/// earlier scan than the last one reopens the file); calls are serialised by a mutex.
class McapScanSource final : public io::ScanSource {
 public:
  /// Opens the file and reads every header stamp once; throws core::FileError
  /// when the file or topic cannot be read or the topic holds no messages.
  McapScanSource(std::string path, std::string topic);
  ~McapScanSource() override;

  [[nodiscard]] std::size_t size() const override { return stamps_.size(); }
  /// Header stamp of message `i` minus that of message 0.
  [[nodiscard]] double stamp(std::size_t i) const override;
  /// Message `i` decoded by McapCloudReader (every channel the message has).
  [[nodiscard]] core::PointCloud scan(std::size_t i) const override;
  /// "mcap PATH topic TOPIC".
  [[nodiscard]] std::string describe() const override;

  /// The header stamp of the first message, s since the epoch (stamp 0).
  [[nodiscard]] double originStamp() const { return origin_; }

 private:
  std::string path_;
  std::string topic_;
  std::vector<double> stamps_;
  double origin_ = 0.0;
  mutable std::mutex mutex_;
  mutable std::unique_ptr<McapCloudReader> reader_;
};

/// Writes a ROS 2 bag as one MCAP file (io::McapWriter: zstd chunks and a
/// summary by default; atomic, moved to its name at `close`). Each message's
/// log and publish time is its header stamp.
class McapBagWriter {
 public:
  /// Creates the temporary file; throws core::FileError if it cannot.
  explicit McapBagWriter(std::string path, io::McapWriteOptions options = {});
  ~McapBagWriter();
  McapBagWriter(const McapBagWriter&) = delete;
  McapBagWriter& operator=(const McapBagWriter&) = delete;

  /// A PointCloud2 of `cloud` (msg::toPointCloud2's layout); `stamp` s since the epoch, >= 0.
  void writeCloud(const std::string& topic, double stamp, const core::PointCloud& cloud,
                  const std::string& frame_id);
  /// A nav_msgs/Odometry with pose `T_frame_child` (covariances and twist zero).
  void writeOdometry(const std::string& topic, double stamp, const Eigen::Isometry3d& T_frame_child,
                     const std::string& frame_id, const std::string& child_frame_id);
  /// A sensor_msgs/Imu, logged at its header stamp.
  void writeImu(const std::string& topic, const msg::Imu& imu);
  /// A geometry_msgs/PoseStamped with pose `T_frame_body`.
  void writePose(const std::string& topic, double stamp, const Eigen::Isometry3d& T_frame_body,
                 const std::string& frame_id);

  /// Finishes the file and moves it to its name; throws core::FileError on failure.
  void close();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dcl::ros2
