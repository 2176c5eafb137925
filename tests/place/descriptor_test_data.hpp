#pragma once

// Real KITTI 00 HDL-64 scans shared by the descriptor tests.

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <string>

#include <dcl/core/point_cloud.hpp>

#include "../common/kitti_test_data.hpp"

namespace dcl::place::test {

using dcl::test::kittiScan;

/// `cloud` turned by `yaw` (rad) about z: the scan a sensor turned by -yaw would see.
inline core::PointCloud rotatedZ(const core::PointCloud& cloud, double yaw) {
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return core::transformed(cloud, T);
}

inline double degrees(double rad) {
  return rad * 180.0 / 3.14159265358979323846;
}
inline double radians(double deg) {
  return deg * 3.14159265358979323846 / 180.0;
}

}  // namespace dcl::place::test
