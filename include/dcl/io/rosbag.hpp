#pragma once

/// ROS1 bags (format 2.0), read without a ROS master: topic listing,
/// `sensor_msgs/PointCloud2` scans, and trajectories from `nav_msgs/Odometry`,
/// `geometry_msgs/PoseStamped` or `geometry_msgs/PoseWithCovarianceStamped`.
///
/// Topic names match with or without their leading '/' ("/points" finds a topic
/// recorded as "points" and the other way round).
///
/// PointCloud2 fields map to core::PointCloud channels by name: x y z (required;
/// FLOAT32 or FLOAT64, or any other type), intensity or i (any type), time or t
/// or timestamp, ring (any integer type). Time conversion: FLOAT32 and FLOAT64
/// values are seconds, integer values (e.g. Ouster's UINT32 `t`) nanoseconds;
/// values beyond 1e6 s (e.g. Hesai's FLOAT64 `timestamp`) are absolute times and
/// are made relative to the message's header stamp. is_bigendian, point_step,
/// row_step, width and height are honoured and checked against the data length;
/// an organised cloud is read row by row into an unorganised one.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include <dcl/core/point_cloud.hpp>
#include <dcl/core/trajectory.hpp>

namespace dcl::io {

/// One topic of a bag.
struct BagTopic {
  std::string name{};        ///< as recorded (with or without a leading '/')
  std::string type{};        ///< message type, e.g. "sensor_msgs/PointCloud2"
  std::size_t messages = 0;  ///< number of messages on the topic
};

/// The topics of the bag at `path`, sorted by name. Throws core::FileError
/// when the bag cannot be opened or read.
std::vector<BagTopic> listBagTopics(const std::string& path);

/// Whether two topic names are the same topic, a leading '/' or not.
bool sameTopic(std::string_view a, std::string_view b);

/// "name (type), ..." of `topics`, or "none": what an error about a missing
/// topic lists.
std::string describeTopics(const std::vector<BagTopic>& topics);

/// A scan and the stamp of its message header.
struct StampedCloud {
  double stamp = 0.0;        ///< header stamp, seconds since the epoch
  core::PointCloud cloud{};  ///< times relative to `stamp`
};

/// How PointCloud2 messages are decoded.
struct BagCloudOptions {
  bool drop_nan = false;  ///< drop points whose x, y or z is not finite; default keep them
};

/// Streams the `sensor_msgs/PointCloud2` messages of one topic, in bag order.
/// Errors are core::FileError naming the bag, the topic and the message index.
class BagCloudReader {
 public:
  /// Opens `path` and selects `topic`; throws core::FileError when the bag cannot
  /// be opened, has no such topic, or the topic is not sensor_msgs/PointCloud2.
  BagCloudReader(const std::string& path, const std::string& topic,
                 const BagCloudOptions& options = {});
  /// Closes the bag.
  ~BagCloudReader();
  /// Takes over the open bag and the position in it.
  BagCloudReader(BagCloudReader&&) noexcept;
  /// Takes over the open bag and the position in it.
  BagCloudReader& operator=(BagCloudReader&&) noexcept;
  BagCloudReader(const BagCloudReader&) = delete;             ///< one reader per open bag
  BagCloudReader& operator=(const BagCloudReader&) = delete;  ///< one reader per open bag

  /// The next scan; none after the last. Throws core::FileError on a corrupt
  /// message, after moving past it (the next call reads the message after it).
  std::optional<StampedCloud> next();

  /// Number of messages on the topic.
  [[nodiscard]] std::size_t size() const;

  /// Number of messages read so far (the 0-based index of the next one).
  [[nodiscard]] std::size_t index() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Every scan of `topic` in `path` (see BagCloudReader).
std::vector<StampedCloud> readBagClouds(const std::string& path, const std::string& topic,
                                        const BagCloudOptions& options = {});

/// One message as recorded: its record time and its serialised bytes.
struct RawBagMessage {
  double time = 0.0;                  ///< record time, s since the epoch
  std::vector<std::uint8_t> bytes{};  ///< the ROS 1 serialisation, for a decoder of its type
};

/// The messages of `topic`, in time order, for a decoder of type `type` (e.g.
/// "sensor_msgs/Imu") whose definition has MD5 sum `md5sum`. Throws
/// core::FileError naming the bag and the topic when the bag cannot be read,
/// the topic is missing, or it holds another type or another definition.
std::vector<RawBagMessage> readBagMessages(const std::string& path, const std::string& topic,
                                           std::string_view type, std::string_view md5sum);

/// The poses T_world_body of `topic` (nav_msgs/Odometry, geometry_msgs/PoseStamped or
/// geometry_msgs/PoseWithCovarianceStamped), stamped from their headers, in bag
/// order; quaternions are normalised. Throws core::FileError naming the bag, the
/// topic and the message index.
core::Trajectory readBagTrajectory(const std::string& path, const std::string& topic);

}  // namespace dcl::io
