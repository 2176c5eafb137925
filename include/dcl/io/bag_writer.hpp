#pragma once

/// Writing ROS1 bags (format 2.0) without ROS: `sensor_msgs/PointCloud2` scans
/// and `nav_msgs/Odometry` poses (and any message serialised elsewhere), readable by rosbag, rviz
/// and io::BagCloudReader.

#include <Eigen/Geometry>
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include <dcl/core/point_cloud.hpp>

namespace dcl::io {

/// Writes one bag. Messages go to a temporary file beside `path` (io::TempFile);
/// `close` renames it to `path`, so an interrupted export never leaves a
/// half-written bag under the final name.
class BagWriter {
 public:
  /// Creates the temporary bag (and parent folders); throws core::FileError if it cannot.
  explicit BagWriter(std::string path);
  /// Removes the temporary file if `close` was not called.
  ~BagWriter();
  BagWriter(const BagWriter&) = delete;
  BagWriter& operator=(const BagWriter&) = delete;

  /// A PointCloud2 with fields x y z intensity (float32), ring (uint16) and time
  /// (float32, s since `stamp`); absent channels are written as 0. `stamp` is the
  /// header and record time, s since the epoch, and must be positive.
  void writeCloud(const std::string& topic, double stamp, const core::PointCloud& cloud,
                  const std::string& frame_id);

  /// A nav_msgs/Odometry with pose `T_frame_child` (covariances and twist zero).
  void writeOdometry(const std::string& topic, double stamp, const Eigen::Isometry3d& T_frame_child,
                     const std::string& frame_id, const std::string& child_frame_id);

  /// A message serialised elsewhere (e.g. ros1::encode) of type `type`, given by
  /// its name, MD5 sum and full definition as ROS 1 holds them.
  void writeSerialised(const std::string& topic, double stamp, std::string_view type,
                       std::string_view md5sum, std::string_view definition,
                       std::vector<std::uint8_t> bytes);

  /// Finishes the bag and moves it to its final name; throws core::FileError on failure.
  void close();

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dcl::io
