#pragma once

// Real data shared by the odometry tests: KITTI 00 scans with their ground
// truth in the LiDAR frame, and the small_gicp outdoor pair.

#include <Eigen/Geometry>
#include <vector>

#include "../common/kitti_test_data.hpp"

namespace dcl::odometry::test {

using dcl::test::dataDir;
using dcl::test::kittiScan;
using dcl::test::PoseError;
using dcl::test::poseError;
using dcl::test::readMatrix4;

/// KITTI 00 ground truth as LiDAR poses.
inline std::vector<Eigen::Isometry3d> kittiLidarGroundTruth() {
  return dcl::test::kittiLidarPoses();
}

/// The ground-truth motion T_i_j between KITTI 00 frames i and j, LiDAR frame.
inline Eigen::Isometry3d kittiMotion(int i, int j) {
  return dcl::test::kittiRelative(i, j);
}

}  // namespace dcl::odometry::test
