#pragma once

// Real KITTI 00 HDL-64 scans shared by the descriptor tests.

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <string>

#include <dcl/core/point_cloud.hpp>
#include <dcl/io/kitti_scan.hpp>

namespace dcl::place::test {

/// The KITTI 00 scan `frame` (0-5, 94, 95, 198, 199 are in the data folder).
inline core::PointCloud kittiScan(int frame) {
  char name[32];
  std::snprintf(name, sizeof(name), "%06d.bin", frame);
  return io::readKittiScan(std::string(DCL_DATA_DIR) + "/lidar_scans/kitti_00/velodyne/" + name);
}

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
