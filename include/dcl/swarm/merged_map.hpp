#pragma once

/// The map of a swarm run (DESIGN.md §3: "the merged map, voxel-filtered,
/// robots coloured"): every keyframe's cloud placed at the keyframe's final
/// estimate, per robot and for all robots together.
///
/// The estimates are only known at the end, after the last optimisation
/// round, so each keyframe's cloud is kept in the keyframe's own frame until
/// then. Kept as floats a HDL-64 keyframe would take about 90 kB even after
/// the map's voxel filter, 90 MB a thousand keyframes; kept in the compact
/// form of the verification clouds (registration/cloud_codec.hpp: 16-bit
/// offsets from the keyframe origin, zstd) it takes about 17 kB.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <dcl/core/config.hpp>
#include <dcl/core/point_cloud.hpp>

namespace dcl::swarm {

/// The map a swarm run keeps and writes.
struct MapConfig {
  static constexpr double kMinVoxel = 0.05;  ///< m, the finest map voxel
  static constexpr double kMaxVoxel = 20.0;  ///< m, the coarsest map voxel

  /// m, voxel edge of the kept keyframe clouds, of each robot's map and of the
  /// merged map (one grid for all, so that a voxel of the merged map gathers
  /// at most one point of each robot's map); 0 keeps no map. 0.4 m is the
  /// grid of LIO-SAM's surface map (mappingSurfLeafSize): on the simulated
  /// KITTI 05 (three HDL-64 robots, 2.2 km) the merged map has 1.15 million
  /// points (17 MB of PLY) and a keyframe's kept cloud takes about 17 kB;
  /// 0.2 m would take 4.4 million points and twice the memory a keyframe.
  double voxel = 0.4;

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    // Finer than the range noise of a LiDAR keeps nearly every point of a scan.
    v.field("voxel", voxel, "m, voxel edge of the kept keyframe clouds and the maps (0: no map)")
        .zeroOrWithin(kMinVoxel, kMaxVoxel, "no map");
  }
};

/// Throws core::Error unless the voxel is 0 or within [0.05, 20] m (visit()).
void validate(const MapConfig& config);

/// One robot's keyframe clouds, each voxel-filtered and stored compactly in
/// the keyframe's own frame, in keyframe order.
class KeyframeClouds {
 public:
  /// Clouds kept at voxel edge `voxel` (m, as MapConfig::voxel; 0 keeps nothing).
  explicit KeyframeClouds(double voxel = MapConfig{}.voxel);

  /// Keeps the next keyframe's cloud (in the keyframe's frame).
  void add(const core::PointCloud& cloud);

  /// Keyframes kept so far.
  [[nodiscard]] std::size_t size() const { return clouds_.size(); }
  /// Bytes their clouds take.
  [[nodiscard]] std::size_t bytes() const { return bytes_; }
  /// The voxel edge they were filtered with (m).
  [[nodiscard]] double voxel() const { return voxel_; }

  /// Keyframe `k`'s filtered cloud, in its frame (within a centimetre an axis
  /// at the default voxel). Throws core::Error for k >= size().
  [[nodiscard]] core::PointCloud cloud(std::size_t k) const;

 private:
  double voxel_;
  std::vector<std::vector<std::uint8_t>> clouds_;
  std::size_t bytes_ = 0;
};

/// A map with one point per occupied voxel: the centroid of the points that
/// fell in it, how many there were, and the robot that gave most of them.
struct VoxelMap {
  std::vector<Eigen::Vector3f> points;  ///< m, in the common frame
  std::vector<std::uint32_t> weights;   ///< keyframe points merged into each
  std::vector<std::uint8_t> robots;     ///< index of the robot each comes from

  [[nodiscard]] std::size_t size() const { return points.size(); }
};

/// Robot `robot`'s map: its keyframe clouds at `T_world_keyframe` (one pose a
/// kept keyframe, in keyframe order), voxel-filtered at the clouds' voxel.
/// Throws core::Error when the poses do not match the clouds.
VoxelMap robotMap(const KeyframeClouds& clouds, std::span<const Eigen::Isometry3d> T_world_keyframe,
                  std::uint8_t robot);

/// The robots' maps together, voxel-filtered again at `voxel` (m, theirs): a
/// point is the weighted centroid of the robots' points in its voxel and
/// belongs to the robot that gave most keyframe points (the first on a tie).
/// Points are in order of first appearance, robot by robot, so the result is
/// deterministic. Throws core::Error for a voxel that is not positive.
VoxelMap mergeMaps(std::span<const VoxelMap> maps, double voxel);

}  // namespace dcl::swarm
