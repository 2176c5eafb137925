#pragma once

// Real data shared by the registration tests: KITTI 00 HDL-64 scans with their
// ground truth in the LiDAR frame, the outdoor scan pair with its two
// published reference transforms, and small scene builders.

#include <Eigen/Geometry>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <string>
#include <vector>

#include <dcl/core/point_cloud.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/io/kitti_scan.hpp>
#include <dcl/io/pcd.hpp>
#include <dcl/io/ply.hpp>
#include <dcl/io/pose_file.hpp>

#include "../common/kitti_test_data.hpp"

namespace dcl::registration::test {

using dcl::test::dataDir;
using dcl::test::kittiScan;
using dcl::test::PoseError;
using dcl::test::poseError;
using dcl::test::readMatrix4;

/// KITTI 00 ground truth as LiDAR poses.
inline const std::vector<Eigen::Isometry3d>& kittiPoses() {
  return dcl::test::kittiLidarPoses();
}

/// The ground-truth pose of KITTI frame `query` in the frame of `candidate`:
/// what verifying `query` against `candidate` must return (T_candidate_query).
inline Eigen::Isometry3d kittiTruth(int query, int candidate) {
  return dcl::test::kittiRelative(candidate, query);
}

/// The outdoor pair: target and source scans and the reference T_target_source,
/// from the PCD folder (fast_gicp's reference) or the PLY folder (small_gicp's).
struct OutdoorPair {
  core::PointCloud target;
  core::PointCloud source;
  Eigen::Isometry3d T_target_source;
};

inline OutdoorPair outdoorPairPcd() {
  const std::string folder = dataDir() + "/lidar_scans/hdl_outdoor_pair_fast_gicp/";
  return {io::readPcd(folder + "251370668.pcd"), io::readPcd(folder + "251371071.pcd"),
          readMatrix4(folder + "relative.txt")};
}

inline OutdoorPair outdoorPairPly() {
  const std::string folder = dataDir() + "/lidar_scans/small_gicp_pair/";
  return {io::readPly(folder + "target.ply"), io::readPly(folder + "source.ply"),
          readMatrix4(folder + "T_target_source.txt")};
}

/// The yaw (rad) of a pose: what place recognition would hand the verification.
inline double yawOf(const Eigen::Isometry3d& T) {
  return std::atan2(T.linear()(1, 0), T.linear()(0, 0));
}

/// Points sampled every `spacing` m on the axis-aligned rectangle spanned from
/// `corner` along `u` and `v` (edge vectors).
inline void addRectangle(std::vector<Eigen::Vector3f>& points, const Eigen::Vector3d& corner,
                         const Eigen::Vector3d& u, const Eigen::Vector3d& v, double spacing) {
  const int nu = static_cast<int>(u.norm() / spacing);
  const int nv = static_cast<int>(v.norm() / spacing);
  for (int i = 0; i <= nu; ++i) {
    for (int j = 0; j <= nv; ++j) {
      const Eigen::Vector3d p =
          corner + u * (i / static_cast<double>(nu)) + v * (j / static_cast<double>(nv));
      points.push_back(p.cast<float>());
    }
  }
}

/// A corridor 4 m wide and 3 m high along x, floor and walls only, 60 m long:
/// nothing fixes a slide along x. When `closed`, it is 20 m long, walls close
/// it at both ends and two pillars stand inside, which fix every direction.
/// When also `symmetric`, the second pillar stands where half a turn about
/// the vertical axis puts the first: the corridor looks the same both ways.
inline core::PointCloud corridor(bool closed, double spacing = 0.1, bool symmetric = false) {
  core::PointCloud cloud;
  auto& p = cloud.points;
  const double half = closed ? 10.0 : 30.0;
  const Eigen::Vector3d x(2.0 * half, 0.0, 0.0);
  addRectangle(p, {-half, -2.0, -1.5}, x, {0.0, 4.0, 0.0}, spacing);  // floor
  addRectangle(p, {-half, -2.0, -1.5}, x, {0.0, 0.0, 3.0}, spacing);  // right wall
  addRectangle(p, {-half, 2.0, -1.5}, x, {0.0, 0.0, 3.0}, spacing);   // left wall
  if (closed) {
    addRectangle(p, {-half, -2.0, -1.5}, {0.0, 4.0, 0.0}, {0.0, 0.0, 3.0}, spacing);
    addRectangle(p, {half, -2.0, -1.5}, {0.0, 4.0, 0.0}, {0.0, 0.0, 3.0}, spacing);
    for (const Eigen::Vector3d& corner :
         {Eigen::Vector3d(4.0, -0.5, -1.5),
          symmetric ? Eigen::Vector3d(-4.6, -0.1, -1.5) : Eigen::Vector3d(-5.0, 0.7, -1.5)}) {
      addRectangle(p, corner, {0.6, 0.0, 0.0}, {0.0, 0.0, 3.0}, spacing);
      addRectangle(p, corner, {0.0, 0.6, 0.0}, {0.0, 0.0, 3.0}, spacing);
      addRectangle(p, corner + Eigen::Vector3d(0.6, 0.0, 0.0), {0.0, 0.6, 0.0}, {0.0, 0.0, 3.0},
                   spacing);
      addRectangle(p, corner + Eigen::Vector3d(0.0, 0.6, 0.0), {0.6, 0.0, 0.0}, {0.0, 0.0, 3.0},
                   spacing);
    }
  }
  return cloud;
}

}  // namespace dcl::registration::test
