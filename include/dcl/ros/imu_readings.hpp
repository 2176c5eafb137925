#pragma once

// An IMU's readings of up by stamp: what levels the scans of a robot over ROS
// (robot --imu) and of a recorded bag (a dataset's `imu_topic`), as a
// simulated robot's IMU levels its own (io::ScanSource::up).

#include <Eigen/Core>
#include <deque>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <dcl/io/scan_source.hpp>
#include <dcl/ros/messages.hpp>

namespace dcl::msg {

/// The rotation of fixed-axis roll, pitch and yaw (deg, about x, y, z).
Eigen::Matrix3d rotationOfRpy(double roll_deg, double pitch_deg, double yaw_deg);

/// Readings of up in the LiDAR frame, kept in stamp order whatever order they come in.
class UpReadings {
 public:
  /// Keeps `imu`'s reading of up (upInLidar) at its header stamp plus
  /// `offset`; false, and nothing kept, when it has no orientation.
  bool add(const Imu& imu, const Eigen::Matrix3d& R_lidar_imu, double offset = 0.0);
  void add(double stamp, const Eigen::Vector3d& up);

  /// The reading nearest `stamp`, if one lies within `max_gap` s of it.
  [[nodiscard]] std::optional<Eigen::Vector3d> nearest(double stamp, double max_gap) const;
  /// Whether a reading at or after `stamp` is in.
  [[nodiscard]] bool reaches(double stamp) const;
  /// Forgets the readings older than `stamp`.
  void dropBefore(double stamp);
  [[nodiscard]] std::size_t size() const { return readings_.size(); }
  /// The newest reading's stamp, if any.
  [[nodiscard]] std::optional<double> newest() const {
    if (readings_.empty()) return std::nullopt;
    return readings_.back().first;
  }

 private:
  std::deque<std::pair<double, Eigen::Vector3d>> readings_;
};

/// A robot's recorded scans, each levelled by the IMU reading nearest its
/// stamp (`origin` + the scans' own stamp, on the readings' clock) within
/// `max_gap` s; none farther.
class LevelledScanSource final : public io::ScanSource {
 public:
  LevelledScanSource(std::unique_ptr<io::ScanSource> scans, UpReadings readings, double origin,
                     double max_gap);

  [[nodiscard]] std::size_t size() const override { return scans_->size(); }
  [[nodiscard]] double stamp(std::size_t i) const override { return scans_->stamp(i); }
  [[nodiscard]] core::PointCloud scan(std::size_t i) const override { return scans_->scan(i); }
  [[nodiscard]] std::optional<Eigen::Vector3d> up(std::size_t i) const override;
  /// The scans' own, and the IMU's.
  [[nodiscard]] std::string describe() const override;

 private:
  std::unique_ptr<io::ScanSource> scans_;
  UpReadings readings_;
  double origin_;
  double max_gap_;
};

}  // namespace dcl::msg

namespace dcl::ros1 {

/// The sensor_msgs/Imu messages of `topic` in a ROS 1 bag, in time order.
/// Throws core::FileError naming the bag, the topic and, for a message that
/// does not decode, its index.
std::vector<msg::Imu> readBagImu(const std::string& path, const std::string& topic);

}  // namespace dcl::ros1
