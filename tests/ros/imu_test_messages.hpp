#pragma once

// The sensor_msgs/Imu values both ROS codecs' tests write and read back, the
// values as Foxglove's reader and genpy name them (the header aside), and
// their comparison.

#include <Eigen/Geometry>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <dcl/ros/messages.hpp>

namespace dcl::test {

/// An AHRS's reading stamped `stamp`: an orientation, rates and
/// accelerations, each with a covariance.
inline msg::Imu imuMessage(double stamp) {
  msg::Imu m;
  m.header = {stamp, "imu_link"};
  // From its matrix, as a decoder checking the norm gives it back.
  m.orientation = Eigen::Quaterniond((Eigen::AngleAxisd(1.2, Eigen::Vector3d::UnitZ()) *
                                      Eigen::AngleAxisd(0.03, Eigen::Vector3d::UnitY()) *
                                      Eigen::AngleAxisd(-0.02, Eigen::Vector3d::UnitX()))
                                         .toRotationMatrix());
  m.orientation_covariance.diagonal() << 1e-6, 1e-6, 4e-4;
  m.angular_velocity = {0.002, -0.001, 0.35};
  m.angular_velocity_covariance.diagonal() << 1e-5, 1e-5, 1e-5;
  m.linear_acceleration = {-1.5, 0.2, 9.75};
  m.linear_acceleration_covariance.diagonal() << 1e-3, 1e-3, 2e-3;
  m.linear_acceleration_covariance(0, 1) = m.linear_acceleration_covariance(1, 0) = 1e-4;
  return m;
}

/// A bare accelerometer and gyro: no orientation (zeros, marked -1).
inline msg::Imu imuWithoutOrientation(double stamp) {
  msg::Imu m = imuMessage(stamp);
  m.orientation.coeffs().setZero();
  m.orientation_covariance.setZero();
  m.orientation_covariance(0, 0) = -1.0;
  return m;
}

/// The message's fields after its header, as both cross-checks name them.
inline nlohmann::json imuFieldsJson(const msg::Imu& m) {
  const auto xyz = [](const Eigen::Vector3d& v) {
    return nlohmann::json{{"x", v.x()}, {"y", v.y()}, {"z", v.z()}};
  };
  const auto covariance = [](const Eigen::Matrix3d& c) {
    nlohmann::json out = nlohmann::json::array();
    for (int r = 0; r < 3; ++r)
      for (int k = 0; k < 3; ++k) out.push_back(c(r, k));
    return out;
  };
  const Eigen::Quaterniond& q = m.orientation;
  return {{"orientation", {{"x", q.x()}, {"y", q.y()}, {"z", q.z()}, {"w", q.w()}}},
          {"orientation_covariance", covariance(m.orientation_covariance)},
          {"angular_velocity", xyz(m.angular_velocity)},
          {"angular_velocity_covariance", covariance(m.angular_velocity_covariance)},
          {"linear_acceleration", xyz(m.linear_acceleration)},
          {"linear_acceleration_covariance", covariance(m.linear_acceleration_covariance)}};
}

/// Every field after the header the same, bit for bit.
inline void expectSameImuFields(const msg::Imu& a, const msg::Imu& b) {
  EXPECT_EQ(a.orientation.coeffs(), b.orientation.coeffs());
  EXPECT_EQ(a.orientation_covariance, b.orientation_covariance);
  EXPECT_EQ(a.angular_velocity, b.angular_velocity);
  EXPECT_EQ(a.angular_velocity_covariance, b.angular_velocity_covariance);
  EXPECT_EQ(a.linear_acceleration, b.linear_acceleration);
  EXPECT_EQ(a.linear_acceleration_covariance, b.linear_acceleration_covariance);
}

}  // namespace dcl::test
