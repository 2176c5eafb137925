#pragma once

// Real data several test suites read: the KITTI 00 HDL-64 scans and their
// ground truth in the LiDAR frame, and the outdoor pairs' reference matrices.

#include <Eigen/Geometry>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include <dcl/core/point_cloud.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/io/kitti_scan.hpp>
#include <dcl/io/pose_file.hpp>

namespace dcl::test {

/// The folder of the shared third-party data.
inline std::string dataDir() {
  return DCL_DATA_DIR;
}

/// KITTI 00 scan `frame` (0-5, 94, 95, 198, 199 are in the data folder; HDL-64,
/// no per-point times).
inline core::PointCloud kittiScan(int frame) {
  char name[16];
  std::snprintf(name, sizeof(name), "%06d.bin", frame);
  return io::readKittiScan(dataDir() + "/lidar_scans/kitti_00/velodyne/" + name);
}

/// KITTI 00 ground truth as LiDAR poses, T_world_lidar = Tr^-1 T_world_cam Tr
/// (read once).
inline const std::vector<Eigen::Isometry3d>& kittiLidarPoses() {
  static const std::vector<Eigen::Isometry3d> poses = [] {
    const auto calib = io::readKittiCalib(dataDir() + "/lidar_scans/kitti_00/calib.txt");
    const auto camera = io::readKittiPoses(dataDir() + "/trajectories/evo/KITTI_00_gt.txt");
    std::vector<Eigen::Isometry3d> lidar;
    for (const auto& T_cam : camera.poses())
      lidar.push_back(calib.T_cam_velo.inverse() * T_cam * calib.T_cam_velo);
    return lidar;
  }();
  return poses;
}

/// The ground-truth pose of KITTI 00 frame `j` in the frame of frame `i`, LiDAR frames.
inline Eigen::Isometry3d kittiRelative(int i, int j) {
  const auto& poses = kittiLidarPoses();
  return poses[static_cast<std::size_t>(i)].inverse() * poses[static_cast<std::size_t>(j)];
}

/// A 4x4 row-major rigid transform as the outdoor pair folders hold it.
inline Eigen::Isometry3d readMatrix4(const std::string& path) {
  std::ifstream in(path);
  Eigen::Matrix4d m;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) in >> m(r, c);
  }
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = core::projectToSO3(m.topLeftCorner<3, 3>());
  T.translation() = m.topRightCorner<3, 1>();
  return T;
}

/// Translation (m) and rotation (deg) of the error between two poses.
struct PoseError {
  double translation = 0.0;
  double rotation_deg = 0.0;
};

inline PoseError poseError(const Eigen::Isometry3d& estimate, const Eigen::Isometry3d& truth) {
  const Eigen::Isometry3d E = truth.inverse() * estimate;
  return {E.translation().norm(), core::rad2deg(core::rotationAngle(E.rotation()))};
}

}  // namespace dcl::test
