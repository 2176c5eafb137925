// Voxel downsampling against a plain std::map reference on real KITTI scans,
// idempotence, and bad input.

#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>

#include <dcl/core/error.hpp>
#include <dcl/registration/voxel_filter.hpp>

#include "registration_test_data.hpp"

namespace dcl::registration {
namespace {

using VoxelIndex = std::tuple<long, long, long>;

VoxelIndex voxelOf(const Eigen::Vector3d& p, double size) {
  return {static_cast<long>(std::floor(p.x() / size)), static_cast<long>(std::floor(p.y() / size)),
          static_cast<long>(std::floor(p.z() / size))};
}

/// The straightforward definition: group by voxel in an ordered map, average.
std::map<VoxelIndex, Eigen::Vector3d> referenceCentroids(const std::vector<Eigen::Vector3f>& points,
                                                         double size) {
  std::map<VoxelIndex, std::pair<Eigen::Vector3d, int>> sums;
  for (const Eigen::Vector3f& p : points) {
    auto& [sum, count] = sums[voxelOf(p.cast<double>(), size)];
    if (count == 0) sum.setZero();
    sum += p.cast<double>();
    ++count;
  }
  std::map<VoxelIndex, Eigen::Vector3d> centroids;
  for (const auto& [voxel, entry] : sums) centroids[voxel] = entry.first / entry.second;
  return centroids;
}

TEST(VoxelFilter, MatchesAReferenceImplementationOnRealScans) {
  for (int frame : {0, 198}) {
    const core::PointCloud scan = test::kittiScan(frame);
    for (double size : {0.3, 0.6, 1.0}) {
      const std::vector<Eigen::Vector3d> filtered = voxelDownsample(scan.points, size);
      const auto reference = referenceCentroids(scan.points, size);
      ASSERT_EQ(filtered.size(), reference.size()) << "frame " << frame << " voxel " << size;
      for (const Eigen::Vector3d& c : filtered) {
        const auto it = reference.find(voxelOf(c, size));
        ASSERT_NE(it, reference.end());  // one centroid per voxel, inside its own voxel
        EXPECT_LT((it->second - c).norm(), 1e-9);
      }
    }
  }
}

TEST(VoxelFilter, IsDeterministicAndIdempotent) {
  const core::PointCloud scan = test::kittiScan(94);
  const std::vector<Eigen::Vector3d> once = voxelDownsample(scan.points, 0.6);
  EXPECT_EQ(voxelDownsample(scan.points, 0.6), once);
  // Each centroid stays in its voxel, so filtering again changes nothing.
  const std::vector<Eigen::Vector3d> twice = voxelDownsample(once, 0.6);
  ASSERT_EQ(twice.size(), once.size());
  for (std::size_t i = 0; i < once.size(); ++i) EXPECT_EQ(twice[i], once[i]);
  EXPECT_LT(once.size(), scan.size() / 5);  // an HDL-64 scan thins out by an order of magnitude
}

TEST(VoxelFilter, AveragesPointsAndKeepsFirstSeenOrder) {
  const std::vector<Eigen::Vector3d> points = {
      {0.1, 0.1, 0.1}, {-0.5, 0.2, 0.2}, {0.3, 0.5, 0.9}, {-0.1, 0.4, 0.8}, {0.9, 0.9, 0.9}};
  const std::vector<Eigen::Vector3d> filtered = voxelDownsample(points, 1.0);
  ASSERT_EQ(filtered.size(), 2U);
  EXPECT_TRUE(filtered[0].isApprox(Eigen::Vector3d(1.3 / 3.0, 1.5 / 3.0, 1.9 / 3.0)));
  EXPECT_TRUE(filtered[1].isApprox(Eigen::Vector3d(-0.3, 0.3, 0.5)));
}

TEST(VoxelFilter, SkipsNonFiniteAndFarPointsAndRejectsBadSizes) {
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<Eigen::Vector3d> points = {
      {1.0, 1.0, 1.0}, {nan, 0.0, 0.0}, {0.0, inf, 0.0}, {1e9, 0.0, 0.0}, {-1e9, 0.0, 0.0}};
  const std::vector<Eigen::Vector3d> filtered = voxelDownsample(points, 0.5);
  ASSERT_EQ(filtered.size(), 1U);
  EXPECT_EQ(filtered[0], points[0]);
  EXPECT_TRUE(voxelDownsample(std::vector<Eigen::Vector3d>{}, 0.5).empty());
  for (double bad : {0.0, -1.0, nan, inf})
    EXPECT_THROW(voxelDownsample(points, bad), core::Error) << bad;
}

TEST(VoxelKey, NamesTheVoxelItsCornerStartsOnRealScans) {
  // Every point of a real scan lies in the voxel its key names, one key a voxel.
  const core::PointCloud scan = test::kittiScan(0);
  const double size = 0.4;
  std::map<VoxelIndex, std::uint64_t> keys;
  for (const Eigen::Vector3f& point : scan.points) {
    const Eigen::Vector3d p = point.cast<double>();
    const std::uint64_t key = voxelKey(p, 1.0 / size);
    ASSERT_NE(key, kNoVoxel);
    const Eigen::Vector3d corner = voxelCorner(key, size);
    EXPECT_TRUE((p.array() >= corner.array() - 1e-9).all() &&
                (p.array() < corner.array() + size + 1e-9).all())
        << p.transpose() << " not in the voxel at " << corner.transpose();
    const auto [it, inserted] = keys.emplace(voxelOf(p, size), key);
    if (!inserted) {
      EXPECT_EQ(it->second, key);
    }
  }
  // Distinct voxels, distinct keys and (for these few) distinct hashes.
  std::map<std::uint64_t, int> hashes;
  for (const auto& [voxel, key] : keys) ++hashes[hashVoxelKey(key)];
  EXPECT_EQ(hashes.size(), keys.size());
  // Negative coordinates floor downwards; the last voxel on each side is kept, the next is not.
  EXPECT_EQ(voxelCorner(voxelKey({-0.1, -2.0, 0.0}, 1.0), 1.0), Eigen::Vector3d(-1.0, -2.0, 0.0));
  EXPECT_NE(voxelKey({kMaxVoxelIndex, -kMaxVoxelIndex, 0.0}, 1.0), kNoVoxel);
  EXPECT_EQ(voxelKey({kMaxVoxelIndex + 1.0, 0.0, 0.0}, 1.0), kNoVoxel);
  EXPECT_EQ(voxelKey({0.0, std::numeric_limits<double>::quiet_NaN(), 0.0}, 1.0), kNoVoxel);
}

}  // namespace
}  // namespace dcl::registration
