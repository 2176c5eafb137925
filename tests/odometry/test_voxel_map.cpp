// The voxel hash map of the local world.

#include <cstddef>
#include <iterator>
#include <map>
#include <random>
#include <tuple>
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

// The odometry's use of the map, a car driving along a street: points added
// ahead, voxels dropped behind and points carved out around it, frame after
// frame, so that voxels leave the table and others take their slots and
// blocks. After every frame the map holds exactly the points a plain
// reference model of it holds, and finds each one from the voxels around it.
TEST(VoxelHashMap, HoldsWhatItWasGivenThroughManyAdditionsAndRemovals) {
  constexpr double kVoxel = 0.5;
  VoxelHashMap map(kVoxel, 3);
  std::map<std::tuple<int, int, int>, std::vector<Eigen::Vector3d>> model;
  std::mt19937 random(7);
  std::uniform_real_distribution<double> around(-6.0, 6.0);
  for (int frame = 0; frame < 60; ++frame) {
    const Eigen::Vector3d car(0.5 * frame, 0.0, 0.0);
    std::vector<Eigen::Vector3d> points;
    for (int i = 0; i < 400; ++i)
      points.emplace_back(car.x() + around(random), around(random), 0.25 * around(random));
    map.addPoints(points);
    for (const Eigen::Vector3d& p : points) {  // the same rules, kept by hand
      const Voxel v = voxelOf(p, kVoxel);
      auto& held = model[{v.x(), v.y(), v.z()}];
      if (held.size() >= 3) continue;
      bool crowded = false;
      for (const Eigen::Vector3d& q : held) crowded |= (q - p).squaredNorm() < kVoxel * kVoxel / 3;
      if (!crowded) held.push_back(p);
    }
    const auto carve = [&](const Eigen::Vector3d& p) { return p.y() > 0.0 && p.z() > 0.5; };
    const std::size_t carved = map.removeNear(car, 3.0, carve);
    std::size_t carved_by_hand = 0;
    for (auto it = model.begin(); it != model.end();) {
      auto& held = it->second;
      if ((held.front() - car).squaredNorm() <= 9.0) carved_by_hand += std::erase_if(held, carve);
      if (!held.empty() && (held.front() - car).squaredNorm() > 7.0 * 7.0) held.clear();
      it = held.empty() ? model.erase(it) : std::next(it);
    }
    map.removeFarFrom(car, 7.0);
    EXPECT_EQ(carved, carved_by_hand) << frame;
    ASSERT_EQ(map.size(), model.size()) << frame;
    std::size_t points_by_hand = 0;
    for (const auto& [voxel, held] : model) {
      points_by_hand += held.size();
      for (const Eigen::Vector3d& p : held) {
        const auto nearest = map.nearest(p);
        ASSERT_TRUE(nearest.has_value()) << frame;
        EXPECT_EQ(nearest->squared_distance, 0.0) << frame;
      }
    }
    EXPECT_EQ(map.pointCount(), points_by_hand) << frame;
    EXPECT_EQ(map.pointCloud().size(), points_by_hand) << frame;
  }
}

}  // namespace
}  // namespace dcl::odometry
