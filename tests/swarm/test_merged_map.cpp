// The map of a swarm run: keyframe clouds kept compact, each robot's map at
// its keyframes' poses, the robots' maps merged, one point a voxel, each
// labelled with the robot that gave most of its points.
#include <cmath>
#include <cstdio>
#include <map>
#include <set>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/io/kitti_scan.hpp>
#include <dcl/registration/voxel_filter.hpp>
#include <dcl/swarm/merged_map.hpp>

#include "../common/sim_convoy.hpp"
#include "map_distance.hpp"

namespace dcl::swarm {
namespace {

using VoxelIndex = std::tuple<long, long, long>;

VoxelIndex voxelOf(const Eigen::Vector3f& p, double voxel) {
  const auto axis = [&](float v) { return static_cast<long>(std::floor(v / voxel)); };
  return {axis(p.x()), axis(p.y()), axis(p.z())};
}

/// Three robots on one street of the small-3 campus, 6 s (about 8 m) apart, so
/// that their maps overlap: each one's keyframes every 2 m of its true route,
/// with their scans and true poses. The scans are not distorted by the motion
/// (but noisy), so that the true poses place them exactly.
struct Street {
  struct Robot {
    KeyframeClouds clouds;
    std::vector<Eigen::Isometry3d> T_world_keyframe;
  };
  std::vector<Robot> robots;

  explicit Street(double voxel) {
    sim::Preset preset = sim::makePreset("small-3");
    const sim::Route street = preset.routes.at(0);
    preset.routes = {test::sliceRoute(street, 120, 80, "a"), test::sliceRoute(street, 60, 80, "b"),
                     test::sliceRoute(street, 0, 80, "c")};
    const auto folder =
        std::filesystem::temp_directory_path() / ("dcl_street_" + std::to_string(::getpid()));
    const io::DatasetSpec spec =
        sim::writeSimDataset(folder.string(), preset, {.motion_distortion = false});
    auto scans = sim::openDatasetScans(spec);
    for (std::size_t r = 0; r < scans.size(); ++r) {
      const core::Trajectory truth = io::readGroundTruth(spec, r);
      Robot robot{KeyframeClouds(voxel), {}};
      for (std::size_t i = 0; i < scans[r]->size(); ++i) {
        const Eigen::Isometry3d T = *truth.at(scans[r]->stamp(i));
        if (!robot.T_world_keyframe.empty() &&
            (T.translation() - robot.T_world_keyframe.back().translation()).norm() < 2.0)
          continue;
        robot.clouds.add(scans[r]->scan(i));
        robot.T_world_keyframe.push_back(T);
      }
      robots.push_back(std::move(robot));
    }
    std::filesystem::remove_all(folder);
  }

  [[nodiscard]] std::vector<VoxelMap> maps() const {
    std::vector<VoxelMap> out;
    for (std::size_t r = 0; r < robots.size(); ++r)
      out.push_back(
          robotMap(robots[r].clouds, robots[r].T_world_keyframe, static_cast<std::uint8_t>(r)));
    return out;
  }
};

const Street& street() {
  static const Street s(MapConfig{}.voxel);
  return s;
}

TEST(KeyframeClouds, KeepAKittiKeyframeInAFewTensOfKilobytes) {
  const core::PointCloud scan =
      io::readKittiScan(std::string(DCL_DATA_DIR) + "/lidar_scans/kitti_00/velodyne/000000.bin");
  ASSERT_GT(scan.size(), 100000u);
  KeyframeClouds clouds;  // the default voxel
  clouds.add(scan);
  ASSERT_EQ(clouds.size(), 1u);
  // A thousand HDL-64 keyframes stay under 40 MB (as floats: about 0.25 MB each).
  EXPECT_LT(clouds.bytes(), 40000u);
  // What comes back is the voxel-filtered scan, within a quantisation step.
  const std::vector<Eigen::Vector3d> filtered =
      registration::voxelDownsample(std::span<const Eigen::Vector3f>(scan.points), clouds.voxel());
  const core::PointCloud kept = clouds.cloud(0);
  ASSERT_EQ(kept.size(), filtered.size());
  EXPECT_GT(static_cast<double>(filtered.size()) * 12.0, 4.0 * static_cast<double>(clouds.bytes()));
  const registration::PointTree tree(filtered);
  for (const Eigen::Vector3f& p : kept.points)
    ASSERT_TRUE(tree.nearest(p.cast<double>(), 0.05 * clouds.voxel()).has_value());
  EXPECT_THROW((void)clouds.cloud(1), core::Error);
}

TEST(KeyframeClouds, ZeroKeepsNothingAndOddVoxelsAreRefused) {
  KeyframeClouds none(0.0);
  none.add(core::PointCloud{{{1.0f, 2.0f, 3.0f}}, {}, {}, {}});
  EXPECT_EQ(none.size(), 0u);
  for (const double bad : {-0.4, 0.01, 25.0, std::nan("")})
    EXPECT_THROW(KeyframeClouds{bad}, core::Error) << bad;
}

TEST(MergedMap, HoldsEveryRobotOnePointAVoxelWithItsMajorityRobot) {
  const std::vector<VoxelMap> maps = street().maps();
  const double voxel = MapConfig{}.voxel;
  const VoxelMap merged = mergeMaps(maps, voxel);

  // Each voxel's weights per robot and weighted sum, computed here independently.
  std::map<VoxelIndex, std::map<std::uint8_t, std::uint64_t>> weights;
  struct Sum {
    Eigen::Vector3d points = Eigen::Vector3d::Zero();
    std::uint64_t weight = 0;
  };
  std::map<VoxelIndex, Sum> sums;
  std::uint64_t total = 0;
  for (const VoxelMap& m : maps) {
    ASSERT_GT(m.size(), 1000u);
    std::set<VoxelIndex> seen;
    for (std::size_t i = 0; i < m.size(); ++i) {
      const VoxelIndex v = voxelOf(m.points[i], voxel);
      EXPECT_TRUE(seen.insert(v).second) << "two points of one robot in a voxel";
      weights[v][m.robots[i]] += m.weights[i];
      sums[v].points += m.points[i].cast<double>() * m.weights[i];
      sums[v].weight += m.weights[i];
      total += m.weights[i];
    }
  }
  // The robots' maps overlap, and the merged map has one point for each occupied voxel.
  ASSERT_EQ(merged.size(), weights.size());
  EXPECT_LT(merged.size(), maps[0].size() + maps[1].size() + maps[2].size());
  std::uint64_t merged_total = 0;
  std::set<std::uint8_t> labels;
  for (std::size_t i = 0; i < merged.size(); ++i) {
    const VoxelIndex v = voxelOf(merged.points[i], voxel);
    ASSERT_TRUE(weights.contains(v));
    std::uint8_t majority = 0;
    std::uint64_t most = 0;
    for (const auto& [robot, w] : weights.at(v)) {
      if (w > most) std::tie(majority, most) = std::tie(robot, w);
    }
    EXPECT_EQ(merged.robots[i], majority);
    EXPECT_EQ(merged.weights[i], sums.at(v).weight);
    const Eigen::Vector3d centroid = sums.at(v).points / static_cast<double>(sums.at(v).weight);
    EXPECT_LT((merged.points[i].cast<double>() - centroid).norm(), 1e-3);
    labels.insert(merged.robots[i]);
    merged_total += merged.weights[i];
  }
  // Every robot keeps its colour somewhere, and no keyframe point is lost on the way.
  EXPECT_EQ(labels, (std::set<std::uint8_t>{0, 1, 2}));
  EXPECT_EQ(merged_total, total);
  std::uint64_t kept = 0;
  for (const Street::Robot& r : street().robots) {
    for (std::size_t k = 0; k < r.clouds.size(); ++k) kept += r.clouds.cloud(k).size();
  }
  EXPECT_EQ(total, kept);
}

TEST(MergedMap, TheVoxelBoundsItsSize) {
  const std::vector<VoxelMap> maps = street().maps();
  const VoxelMap fine = mergeMaps(maps, MapConfig{}.voxel);
  const VoxelMap coarse = mergeMaps(maps, 2.0 * MapConfig{}.voxel);
  // Twice the edge, a quarter of the voxels on a surface sampled densely
  // enough; the VLP-16's rings far away are not, and lose fewer.
  EXPECT_LT(coarse.size(), fine.size() / 2);
  EXPECT_GT(coarse.size(), fine.size() / 8);
  std::set<VoxelIndex> voxels;
  for (const Eigen::Vector3f& p : coarse.points)
    EXPECT_TRUE(voxels.insert(voxelOf(p, 2.0 * MapConfig{}.voxel)).second);
}

TEST(MergedMap, TheRobotsMapsCoincideAtTheTruePoses) {
  const std::vector<VoxelMap> maps = street().maps();
  // Where the robots saw the same street, their maps lie on the same surfaces,
  // within the sensors' noise, their lasers' calibration errors and the
  // foliage's scatter (0.027-0.037 m)...
  for (std::size_t r = 1; r < 3; ++r) {
    const test::MapDistance d = test::mapDistance(maps[r], maps[r - 1]);
    EXPECT_GT(d.points, maps[r].size() / 3) << r;
    std::printf("median distance of %zu's map to %zu's: %.4f m\n", r, r - 1, d.median);
    EXPECT_LT(d.median, 0.045) << r;
  }
  // ...which they do not when each cloud is placed at the next keyframe's pose,
  // or robot b's map is 10 cm off (0.08 m).
  const Street::Robot& b = street().robots.at(1);
  std::vector<Eigen::Isometry3d> next = b.T_world_keyframe;
  std::rotate(next.begin(), next.begin() + 1, next.end());
  const double at_next = test::mapDistance(robotMap(b.clouds, next, 1), maps[0]).median;
  std::vector<Eigen::Isometry3d> off = b.T_world_keyframe;
  for (Eigen::Isometry3d& T : off) T.translation().x() += 0.1;
  const double moved = test::mapDistance(robotMap(b.clouds, off, 1), maps[0]).median;
  std::printf(
      "median distance to a's map: b at the next keyframe's poses %.4f m, 10 cm off %.4f m\n",
      at_next, moved);
  EXPECT_GT(at_next, 0.06);
  EXPECT_GT(moved, 0.06);
}

TEST(MergedMap, RefusesPosesThatDoNotFitTheClouds) {
  const Street::Robot& a = street().robots.at(0);
  std::vector<Eigen::Isometry3d> poses = a.T_world_keyframe;
  poses.pop_back();
  EXPECT_THROW((void)robotMap(a.clouds, poses, 0), core::Error);
  EXPECT_THROW((void)mergeMaps({}, 0.0), core::Error);
}

}  // namespace
}  // namespace dcl::swarm
