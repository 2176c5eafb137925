// Loop verification on real KITTI 00 HDL-64 scans, one core: a verification
// against a scan and against a submap of five keyframes, a refused candidate
// (which runs the RANSAC fallback), the FPFH + RANSAC global registration
// alone, the voxel filter, and the compact verification cloud's codec.
// Target (BENCHMARKS.md): one verification of an HDL-64 keyframe < 50 ms.
#include <cmath>
#include <cstdio>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include <dcl/core/se3.hpp>
#include <dcl/io/kitti_scan.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/registration/cloud_codec.hpp>
#include <dcl/registration/fpfh.hpp>
#include <dcl/registration/ransac.hpp>
#include <dcl/registration/verification.hpp>
#include <dcl/registration/voxel_filter.hpp>

namespace {

namespace reg = dcl::registration;

const std::string kKitti = std::string(DCL_DATA_DIR) + "/lidar_scans/kitti_00/";

dcl::core::PointCloud scan(int frame) {
  char name[16];
  std::snprintf(name, sizeof(name), "%06d.bin", frame);
  return dcl::io::readKittiScan(kKitti + "velodyne/" + name);
}

/// KITTI 00 ground truth in the LiDAR frame.
Eigen::Isometry3d lidarPose(int frame) {
  static const std::vector<Eigen::Isometry3d> poses = [] {
    const auto calib = dcl::io::readKittiCalib(kKitti + "calib.txt");
    const auto camera =
        dcl::io::readKittiPoses(std::string(DCL_DATA_DIR) + "/trajectories/evo/KITTI_00_gt.txt");
    std::vector<Eigen::Isometry3d> lidar;
    for (const auto& T : camera.poses())
      lidar.push_back(calib.T_cam_velo.inverse() * T * calib.T_cam_velo);
    return lidar;
  }();
  return poses[static_cast<std::size_t>(frame)];
}

/// Frames 0, 1, 2, 4 and 5 in the frame of frame 3: the submap a verifier
/// holds around its keyframe 3 (621,644 points).
const dcl::core::PointCloud& submapAround3() {
  static const dcl::core::PointCloud submap = [] {
    dcl::core::PointCloud s;
    for (int frame : {0, 1, 2, 4, 5}) {
      dcl::core::PointCloud c = scan(frame);
      c.intensity.clear();
      s.append(dcl::core::transformed(c, lidarPose(3).inverse() * lidarPose(frame)));
    }
    return s;
  }();
  return submap;
}

double yawOf(const Eigen::Isometry3d& T) {
  return std::atan2(T.linear()(1, 0), T.linear()(0, 0));
}

void BM_VoxelDownsampleScan(benchmark::State& state) {
  const dcl::core::PointCloud cloud = scan(0);
  for (auto _ : state) benchmark::DoNotOptimize(reg::voxelDownsample(cloud.points, 0.6));
  state.counters["points"] = static_cast<double>(cloud.size());
}
BENCHMARK(BM_VoxelDownsampleScan)->Unit(benchmark::kMillisecond);

void BM_VerifyScanPair(benchmark::State& state) {
  const dcl::core::PointCloud query = scan(94);
  const dcl::core::PointCloud candidate = scan(95);
  const double yaw = yawOf(lidarPose(95).inverse() * lidarPose(94));
  reg::VerificationResult result;
  for (auto _ : state) result = reg::verifyLoop(query, yaw, candidate);
  state.counters["accepted"] = result.accepted ? 1 : 0;
  state.counters["iterations"] = result.iterations;
}
BENCHMARK(BM_VerifyScanPair)->Unit(benchmark::kMillisecond);

void BM_VerifySubmap(benchmark::State& state) {
  const dcl::core::PointCloud query = scan(3);
  reg::VerificationResult result;
  for (auto _ : state) result = reg::verifyLoop(query, 0.0, submapAround3());
  state.counters["accepted"] = result.accepted ? 1 : 0;
  state.counters["submap_points"] = static_cast<double>(result.submap_points);
}
BENCHMARK(BM_VerifySubmap)->Unit(benchmark::kMillisecond);

void BM_VerifyCompactQuerySubmap(benchmark::State& state) {
  const dcl::core::PointCloud query =
      reg::decodeVerificationCloud(reg::encodeVerificationCloud(scan(3)));
  reg::VerificationResult result;
  for (auto _ : state) result = reg::verifyLoop(query, 0.0, submapAround3());
  state.counters["accepted"] = result.accepted ? 1 : 0;
}
BENCHMARK(BM_VerifyCompactQuerySubmap)->Unit(benchmark::kMillisecond);

void BM_VerifyRejected(benchmark::State& state) {
  const dcl::core::PointCloud query = scan(0);
  const dcl::core::PointCloud candidate = scan(198);
  reg::VerificationResult result;
  for (auto _ : state) result = reg::verifyLoop(query, 0.0, candidate);
  state.counters["accepted"] = result.accepted ? 1 : 0;
}
BENCHMARK(BM_VerifyRejected)->Unit(benchmark::kMillisecond);

void BM_FpfhRansac(benchmark::State& state) {
  // Frame 94 turned around: no heading to start from.
  const dcl::core::PointCloud query =
      dcl::core::transformed(scan(94), dcl::core::makePose2d(0.0, 0.0, 3.14159));
  const std::vector<Eigen::Vector3d> q = reg::voxelDownsample(query.points, 1.0);
  const std::vector<Eigen::Vector3d> c = reg::voxelDownsample(scan(95).points, 1.0);
  reg::RansacResult result;
  for (auto _ : state) {
    reg::RegistrationCloud source(q);
    reg::RegistrationCloud target(c);
    const auto matches = reg::matchFeatures(reg::computeFpfh(source), reg::computeFpfh(target));
    result = reg::ransacRegistration(source.points(), target.points(), matches);
  }
  state.counters["found"] = result.found ? 1 : 0;
  state.counters["points"] = static_cast<double>(q.size());
}
BENCHMARK(BM_FpfhRansac)->Unit(benchmark::kMillisecond);

void BM_EncodeVerificationCloud(benchmark::State& state) {
  const dcl::core::PointCloud cloud = scan(0);
  std::size_t bytes = 0;
  for (auto _ : state) bytes = reg::encodeVerificationCloud(cloud).size();
  state.counters["bytes"] = static_cast<double>(bytes);
}
BENCHMARK(BM_EncodeVerificationCloud)->Unit(benchmark::kMillisecond);

void BM_DecodeVerificationCloud(benchmark::State& state) {
  const std::vector<std::uint8_t> bytes = reg::encodeVerificationCloud(scan(0));
  for (auto _ : state) benchmark::DoNotOptimize(reg::decodeVerificationCloud(bytes));
  state.counters["bytes"] = static_cast<double>(bytes.size());
}
BENCHMARK(BM_DecodeVerificationCloud)->Unit(benchmark::kMicrosecond);

}  // namespace
