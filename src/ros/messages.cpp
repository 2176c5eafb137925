#include <cmath>
#include <utility>

#include <dcl/ros/messages.hpp>

namespace dcl::msg {

PointCloud2 toPointCloud2(const core::PointCloud& cloud, Header header) {
  io::PointCloud2Data data = io::encodePointCloud2(cloud);
  PointCloud2 m;
  m.header = std::move(header);
  m.width = static_cast<std::uint32_t>(cloud.size());
  m.fields = std::move(data.fields);
  m.point_step = data.point_step;
  m.row_step = m.width * m.point_step;
  m.data = std::move(data.data);
  return m;
}

std::optional<Eigen::Vector3d> upInLidar(const Imu& imu, const Eigen::Matrix3d& R_lidar_imu) {
  if (!imu.hasOrientation()) return std::nullopt;
  // The world's up in the IMU frame: the last row of R_world_imu.
  const Eigen::Vector3d up_imu = imu.orientation.normalized().toRotationMatrix().row(2).transpose();
  const Eigen::Vector3d up = R_lidar_imu * up_imu;
  if (!up.allFinite()) return std::nullopt;
  return up.normalized();
}

Imu imuOfUp(const Eigen::Vector3d& up_lidar, double tilt_variance, Header header) {
  Imu m;
  m.header = std::move(header);
  // The least rotation taking the reading to the world's up: R_world_lidar with yaw 0.
  m.orientation =
      Eigen::Quaterniond::FromTwoVectors(up_lidar.normalized(), Eigen::Vector3d::UnitZ());
  m.orientation_covariance.diagonal() << tilt_variance, tilt_variance, 4.0 * M_PI * M_PI;
  m.angular_velocity_covariance(0, 0) = -1.0;
  m.linear_acceleration_covariance(0, 0) = -1.0;
  return m;
}

io::PointCloud2View PointCloud2::view() const {
  return {height, width, fields, is_bigendian, point_step, row_step, data};
}

}  // namespace dcl::msg
