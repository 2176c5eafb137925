// Scan preprocessing: cleaning, deskewing, voxel downsampling.

#include <cmath>
#include <limits>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/odometry/preprocessing.hpp>

namespace dcl::odometry {
namespace {

core::PointCloud cloudWithChannels(const std::vector<Eigen::Vector3f>& points) {
  core::PointCloud cloud;
  for (std::size_t i = 0; i < points.size(); ++i) {
    cloud.points.push_back(points[i]);
    cloud.intensity.push_back(static_cast<float>(i));
    cloud.time.push_back(0.01f * static_cast<float>(i));
    cloud.ring.push_back(static_cast<std::uint16_t>(i));
  }
  return cloud;
}

TEST(CleanScan, DropsNonFiniteAndOutOfRangePointsKeepingChannelsAligned) {
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  const auto cloud = cloudWithChannels(
      {{5, 0, 0}, {nan, 0, 0}, {0.5f, 0, 0}, {0, inf, 0}, {0, 50, 0}, {0, 0, 150}, {3, 4, 0}});
  const CleanScan clean = cleanScan(cloud, 1.0, 100.0);
  ASSERT_EQ(clean.cloud.size(), 3u);
  EXPECT_TRUE(clean.cloud.consistent());
  EXPECT_EQ(clean.non_finite, 2u);
  EXPECT_EQ(clean.out_of_range, 2u);
  EXPECT_EQ(clean.cloud.intensity, (std::vector<float>{0, 4, 6}));
  EXPECT_EQ(clean.cloud.ring, (std::vector<std::uint16_t>{0, 4, 6}));
  EXPECT_FLOAT_EQ(clean.cloud.time[2], 0.06f);
}

TEST(CleanScan, DropsPointsWithNonFiniteTimes) {
  auto cloud = cloudWithChannels({{5, 0, 0}, {6, 0, 0}});
  cloud.time[1] = std::numeric_limits<float>::quiet_NaN();
  const CleanScan clean = cleanScan(cloud, 1.0, 100.0);
  EXPECT_EQ(clean.cloud.size(), 1u);
  EXPECT_EQ(clean.bad_time, 1u);
}

TEST(CleanScan, EmptyScanGivesEmptyResult) {
  const CleanScan clean = cleanScan(core::PointCloud{}, 1.0, 100.0);
  EXPECT_TRUE(clean.cloud.empty());
}

TEST(Deskew, MapsEveryPointToTheSensorAtTheReferenceTime) {
  // A sensor moving at 10 m/s and turning at 30 deg/s sees fixed world points.
  core::Vector6d velocity;
  velocity << 10.0, 0.5, 0.0, 0.0, 0.0, core::deg2rad(30.0);
  const std::vector<Eigen::Vector3d> world{{20, 5, 1}, {-8, 12, 0}, {3, -30, 2}, {0, 0, 5}};
  core::PointCloud scan;
  for (std::size_t i = 0; i < world.size(); ++i) {
    const double t = 0.1 * static_cast<double>(i) / 3.0;  // fired over a 0.1 s sweep
    const Eigen::Isometry3d T_stamp_t = core::expSE3(t * velocity);
    scan.points.push_back((T_stamp_t.inverse() * world[i]).cast<float>());
    scan.time.push_back(static_cast<float>(t));
  }
  for (const double reference : {0.0, 0.05}) {
    const auto points = deskew(scan, velocity, reference);
    const Eigen::Isometry3d T_ref_stamp = core::expSE3(reference * velocity).inverse();
    for (std::size_t i = 0; i < world.size(); ++i) {
      EXPECT_LT((points[i] - T_ref_stamp * world[i]).norm(), 2e-3) << "point " << i;
    }
  }
}

TEST(Deskew, LeavesACloudWithoutTimesUnchanged) {
  core::PointCloud scan;
  scan.points = {{1, 2, 3}, {4, 5, 6}};
  core::Vector6d velocity = core::Vector6d::Constant(1.0);
  const auto points = deskew(scan, velocity, 0.05);
  EXPECT_TRUE(points[1].isApprox(Eigen::Vector3d(4, 5, 6)));
  EXPECT_EQ(sweepMidTime(scan), 0.0);
}

TEST(Deskew, SweepMidTimeIsTheMiddleOfTheTimes) {
  auto cloud = cloudWithChannels({{1, 0, 0}, {2, 0, 0}, {3, 0, 0}});
  EXPECT_NEAR(sweepMidTime(cloud), 0.01, 1e-7);
}

TEST(VoxelDownsample, KeepsTheFirstPointOfEachVoxelInOrder) {
  const std::vector<Eigen::Vector3d> points{
      {0.1, 0.1, 0.1}, {0.2, 0.2, 0.2}, {1.5, 0.1, 0.1}, {-0.1, 0.1, 0.1}, {1.9, 0.9, 0.9}};
  const auto kept = voxelDownsample(points, 1.0);
  ASSERT_EQ(kept.size(), 3u);
  EXPECT_EQ(kept[0], points[0]);
  EXPECT_EQ(kept[1], points[2]);
  EXPECT_EQ(kept[2], points[3]);  // x = -0.1 floors to voxel -1
  EXPECT_TRUE(voxelDownsample({}, 1.0).empty());
}

TEST(VoxelDownsample, IsDeterministic) {
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 5000; ++i) {
    points.emplace_back(std::sin(i) * 30.0, std::cos(i * 0.7) * 30.0, std::sin(i * 1.3) * 3.0);
  }
  EXPECT_EQ(voxelDownsample(points, 0.5), voxelDownsample(points, 0.5));
}

TEST(Conversion, PointsAndCloudRoundTrip) {
  const std::vector<Eigen::Vector3d> points{{1.5, -2.25, 3.0}};
  const auto cloud = toCloud(points);
  EXPECT_EQ(toPoints(cloud), points);
}

}  // namespace
}  // namespace dcl::odometry
