// The simulated external front-end: the ground truth drifting as asked, on the
// real KITTI 05 ground truth (2.2 km of streets), measured with the KITTI metric.

#include <cmath>
#include <string>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/eval/association.hpp>
#include <dcl/eval/rpe.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/sim/drifting_odometry.hpp>

namespace dcl::sim {
namespace {

/// KITTI 05's ground truth as a z-up body's poses (the file's are the camera's:
/// x right, y down, z forward), as the simulator's routes are.
core::Trajectory kitti05() {
  const core::Trajectory camera =
      io::readKittiPoses(std::string(DCL_DATA_DIR) + "/trajectories/kitti_gt_poses/05.txt");
  Eigen::Isometry3d T_camera_body = Eigen::Isometry3d::Identity();
  T_camera_body.linear() << 0, -1, 0, 0, 0, -1, 1, 0, 0;
  core::Trajectory body;
  for (std::size_t i = 0; i < camera.size(); ++i)
    body.push_back(camera.stamp(i), camera.pose(i) * T_camera_body);
  return body;
}

TEST(DriftingOdometry, DriftsAsAskedByTheKittiMetric) {
  const core::Trajectory truth = kitti05();
  for (const std::uint64_t seed : {1u, 2u, 3u, 4u}) {
    SCOPED_TRACE(seed);
    const core::Trajectory reported = driftingOdometry(
        truth, {.translation_percent = 1.0, .rotation_deg_per_m = 0.01, .seed = seed});
    ASSERT_EQ(reported.size(), truth.size());
    EXPECT_LT((reported.pose(0).translation() - truth.pose(0).translation()).norm(), 1e-9);
    const auto kitti = eval::computeKittiMetric(eval::associateByIndex(reported, truth));
    ASSERT_TRUE(kitti.has_value());
    // The rotation error grows by 0.01 deg a metre; the translation error is the
    // 1 % scale error plus what the turned heading adds over a segment (about
    // 0.01 deg/m x L / 2 of its length L, 100 to 800 m).
    EXPECT_NEAR(kitti->rotation_deg_per_m, 0.01, 0.001);
    EXPECT_GT(kitti->translation_percent, 1.5);
    EXPECT_LT(kitti->translation_percent, 3.0);
  }
}

TEST(DriftingOdometry, WithoutDriftItIsTheTruthUpToItsJitter) {
  const core::Trajectory truth = kitti05();
  const core::Trajectory exact = driftingOdometry(
      truth,
      {.translation_percent = 0.0, .rotation_deg_per_m = 0.0, .jitter_m = 0.0, .jitter_deg = 0.0});
  for (std::size_t i = 0; i < truth.size(); i += 100) {
    EXPECT_LT((exact.pose(i).translation() - truth.pose(i).translation()).norm(), 1e-6) << i;
  }
  const core::Trajectory jittered =
      driftingOdometry(truth, {.translation_percent = 0.0, .rotation_deg_per_m = 0.0});
  const auto kitti = eval::computeKittiMetric(eval::associateByIndex(jittered, truth));
  ASSERT_TRUE(kitti.has_value());
  EXPECT_LT(kitti->translation_percent, 0.3);
}

TEST(DriftingOdometry, SeedsGiveOtherDrifts) {
  const core::Trajectory truth = kitti05();
  const Eigen::Vector3d a = driftingOdometry(truth, {.seed = 1}).poses().back().translation();
  const Eigen::Vector3d b = driftingOdometry(truth, {.seed = 2}).poses().back().translation();
  EXPECT_GT((a - b).norm(), 1.0);
}

TEST(DriftingOdometry, RefusesNegativeOrNonFiniteFigures) {
  const core::Trajectory truth = kitti05();
  EXPECT_THROW(driftingOdometry(truth, {.translation_percent = -1.0}), core::Error);
  EXPECT_THROW(driftingOdometry(truth, {.rotation_deg_per_m = NAN}), core::Error);
  EXPECT_THROW(driftingOdometry(truth, {.jitter_m = INFINITY}), core::Error);
}

}  // namespace
}  // namespace dcl::sim
