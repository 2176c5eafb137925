// The voxel hash map of the local world.

#include <vector>

#include <gtest/gtest.h>

#include <dcl/odometry/voxel_map.hpp>

namespace dcl::odometry {
namespace {

TEST(VoxelOf, FloorsNegativeCoordinates) {
  EXPECT_EQ(voxelOf(Eigen::Vector3d(0.5, -0.5, 1.99), 1.0), Voxel(0, -1, 1));
  EXPECT_EQ(voxelOf(Eigen::Vector3d(-2.0, 2.0, -0.01), 0.5), Voxel(-4, 4, -1));
}

TEST(VoxelHashMap, CapsPointsPerVoxelAndKeepsThemApart) {
  VoxelHashMap map(1.0, 4);  // points at least 1 / sqrt(4) = 0.5 m apart
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 10; ++i) points.emplace_back(0.1 * i, 0.05, 0.05);
  points.emplace_back(0.05, 0.95, 0.05);
  points.emplace_back(0.95, 0.95, 0.95);
  points.emplace_back(0.05, 0.05, 0.95);
  map.addPoints(points);
  EXPECT_EQ(map.size(), 1u);
  EXPECT_EQ(map.pointCount(), 4u);  // (0,0,0), (0.5,0,0), (0,0.95,0), (0.95,0.95,0.95)
}

TEST(VoxelHashMap, FindsTheNearestPointInNeighbouringVoxels) {
  VoxelHashMap map(1.0, 20);
  map.addPoints(std::vector<Eigen::Vector3d>{{0.9, 0.5, 0.5}, {2.5, 0.5, 0.5}});
  const auto nearest = map.nearest(Eigen::Vector3d(1.2, 0.5, 0.5));
  ASSERT_TRUE(nearest.has_value());
  EXPECT_TRUE(nearest->point.isApprox(Eigen::Vector3d(0.9, 0.5, 0.5)));
  EXPECT_NEAR(nearest->squared_distance, 0.09, 1e-12);
  EXPECT_FALSE(map.nearest(Eigen::Vector3d(10, 10, 10)).has_value());
  EXPECT_FALSE(VoxelHashMap(1.0, 20).nearest(Eigen::Vector3d::Zero()).has_value());
}

TEST(VoxelHashMap, NeighborsAreSortedByDistance) {
  VoxelHashMap map(1.0, 20);
  map.addPoints(std::vector<Eigen::Vector3d>{{0.1, 0, 0}, {0.9, 0, 0}, {0.5, 0, 0}, {-0.6, 0, 0}});
  const auto neighbors = map.neighbors(Eigen::Vector3d(0.45, 0, 0), 3);
  ASSERT_EQ(neighbors.size(), 3u);
  EXPECT_DOUBLE_EQ(neighbors[0].x(), 0.5);
  EXPECT_DOUBLE_EQ(neighbors[1].x(), 0.1);
  EXPECT_DOUBLE_EQ(neighbors[2].x(), 0.9);
}

TEST(VoxelHashMap, AddsTransformedPointsAndRemovesFarVoxels) {
  VoxelHashMap map(1.0, 20);
  const Eigen::Isometry3d T_map_sensor(Eigen::Translation3d(100.0, 0.0, 0.0));
  map.addPoints(std::vector<Eigen::Vector3d>{{0.5, 0.5, 0.5}, {50.5, 0.5, 0.5}}, T_map_sensor);
  EXPECT_EQ(map.size(), 2u);
  const auto cloud = map.pointCloud();
  EXPECT_TRUE(cloud[0].x() > 99.0);
  map.removeFarFrom(Eigen::Vector3d(100.0, 0.0, 0.0), 10.0);
  ASSERT_EQ(map.size(), 1u);
  EXPECT_NEAR(map.pointCloud()[0].x(), 100.5, 1e-12);
  map.clear();
  EXPECT_TRUE(map.empty());
}

}  // namespace
}  // namespace dcl::odometry
