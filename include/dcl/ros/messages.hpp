#pragma once

// The ROS messages a robot reads and publishes, as values. ROS 1 and ROS 2
// define them alike (ROS 1's header adds a sequence number, not kept here);
// ros1_messages.hpp and ros2_messages.hpp turn them into each one's bytes.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include <dcl/core/point_cloud.hpp>
#include <dcl/io/point_cloud2.hpp>

namespace dcl::msg {

/// std_msgs/Header; the stamp in seconds since the Unix epoch.
struct Header {
  double stamp = 0.0;
  std::string frame_id{};
};

/// sensor_msgs/PointCloud2 (io::decodePointCloud2 reads its points).
struct PointCloud2 {
  Header header{};
  std::uint32_t height = 1;
  std::uint32_t width = 0;
  std::vector<io::PointField> fields{};
  bool is_bigendian = false;
  std::uint32_t point_step = 0;
  std::uint32_t row_step = 0;
  std::vector<std::uint8_t> data{};
  bool is_dense = true;

  /// The cloud's fields and data borrowed, for io::decodePointCloud2.
  [[nodiscard]] io::PointCloud2View view() const;
};

/// `cloud` as a PointCloud2 stamped `header`: one row, the layout of
/// io::encodePointCloud2. Throws core::Error if its channels differ in length.
PointCloud2 toPointCloud2(const core::PointCloud& cloud, Header header);

/// nav_msgs/Odometry: the pose of child_frame_id in header.frame_id, its twist
/// in child_frame_id; covariances row-major in (x, y, z, roll, pitch, yaw).
struct Odometry {
  Header header{};
  std::string child_frame_id{};
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  Eigen::Matrix<double, 6, 6> pose_covariance = Eigen::Matrix<double, 6, 6>::Zero();
  Eigen::Vector3d linear_velocity = Eigen::Vector3d::Zero();   ///< m/s
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();  ///< rad/s
  Eigen::Matrix<double, 6, 6> twist_covariance = Eigen::Matrix<double, 6, 6>::Zero();
};

/// sensor_msgs/Imu: the IMU frame's orientation in a frame whose z is up
/// (REP 145: ENU), its angular velocity (rad/s) and linear acceleration
/// (m/s^2) in the IMU frame; each covariance row-major about x, y, z, and an
/// element (0, 0) of -1 where the IMU gives no such estimate.
struct Imu {
  Header header{};
  Eigen::Quaterniond orientation = Eigen::Quaterniond::Identity();
  Eigen::Matrix3d orientation_covariance = Eigen::Matrix3d::Zero();
  Eigen::Vector3d angular_velocity = Eigen::Vector3d::Zero();
  Eigen::Matrix3d angular_velocity_covariance = Eigen::Matrix3d::Zero();
  Eigen::Vector3d linear_acceleration = Eigen::Vector3d::Zero();
  Eigen::Matrix3d linear_acceleration_covariance = Eigen::Matrix3d::Zero();

  /// False where orientation_covariance(0, 0) is -1: the orientation is no estimate.
  [[nodiscard]] bool hasOrientation() const { return orientation_covariance(0, 0) != -1.0; }
};

/// An IMU reading of up, as the built-in odometry levels with it: the
/// direction against gravity in the LiDAR's frame, from the message's
/// orientation (its roll and pitch; the yaw does not matter) and the IMU's
/// rotation in the LiDAR frame, `R_lidar_imu`. None when the message has no
/// orientation: its acceleration alone holds the vehicle's own acceleration
/// too (a car braking at 2 m/s^2 reads 12 deg off up), and an orientation
/// filter (the IMU's own, or e.g. imu_filter_madgwick) is what takes it out.
std::optional<Eigen::Vector3d> upInLidar(const Imu& imu, const Eigen::Matrix3d& R_lidar_imu);

/// An IMU message that says only `up_lidar` (the LiDAR's reading of up, with
/// the IMU at the LiDAR): an orientation of that roll and pitch and yaw 0,
/// roll and pitch variance `tilt_variance` (rad^2), the yaw's marked unknown
/// (a variance of 4 pi^2), no angular velocity and no acceleration (-1).
Imu imuOfUp(const Eigen::Vector3d& up_lidar, double tilt_variance, Header header);

/// geometry_msgs/PoseStamped.
struct PoseStamped {
  Header header{};
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
};

/// nav_msgs/Path.
struct Path {
  Header header{};
  std::vector<PoseStamped> poses{};
};

/// geometry_msgs/TransformStamped: child_frame_id's pose in header.frame_id.
struct TransformStamped {
  Header header{};
  std::string child_frame_id{};
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
};

/// tf2_msgs/TFMessage.
struct TFMessage {
  std::vector<TransformStamped> transforms{};
};

/// std_msgs/ColorRGBA, each in [0, 1].
struct ColorRGBA {
  float r = 0.0F;
  float g = 0.0F;
  float b = 0.0F;
  float a = 1.0F;

  bool operator==(const ColorRGBA&) const = default;
};

/// visualization_msgs/Marker, the fields a robot fills (the texture, UV and
/// mesh fields are written empty and ignored when read).
struct Marker {
  static constexpr std::int32_t kLineList = 5;
  static constexpr std::int32_t kSphereList = 7;
  static constexpr std::int32_t kAdd = 0;
  static constexpr std::int32_t kDeleteAll = 3;

  Header header{};
  std::string ns{};
  std::int32_t id = 0;
  std::int32_t type = kLineList;
  std::int32_t action = kAdd;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  Eigen::Vector3d scale = Eigen::Vector3d::Ones();
  ColorRGBA color{};
  double lifetime = 0.0;  ///< s, 0: forever
  bool frame_locked = false;
  std::vector<Eigen::Vector3d> points{};
  std::vector<ColorRGBA> colors{};
  std::string text{};
};

/// visualization_msgs/MarkerArray.
struct MarkerArray {
  std::vector<Marker> markers{};
};

}  // namespace dcl::msg
