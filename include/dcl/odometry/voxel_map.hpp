#pragma once

/// The local map of the LiDAR odometry: a hash of integer voxel coordinates to
/// a few points each (KISS-ICP's VoxelHashMap, Vizzo et al. 2023). Bounded
/// points per voxel keep the map sparse and uniform; culling by distance keeps
/// it local, so memory and search cost do not grow with the trajectory.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

namespace dcl::odometry {

/// Integer coordinates of a voxel: floor(p / voxel_size) per axis.
using Voxel = Eigen::Vector3i;

/// The voxel of `point` for voxels of edge `voxel_size`.
Voxel voxelOf(const Eigen::Vector3d& point, double voxel_size);

/// Spatial hash of a voxel (the three-prime hash of Teschner et al. 2003).
struct VoxelHash {
  /// The hash of `voxel`.
  std::size_t operator()(const Voxel& voxel) const noexcept;
};

/// The first slot of `voxel` in an open-addressing table of 2^(64 - `shift`)
/// slots: Fibonacci hashing of VoxelHash, which spreads neighbouring voxels
/// over the table.
inline std::size_t voxelSlot(const Voxel& voxel, int shift) {
  return static_cast<std::size_t>(
      (static_cast<std::uint64_t>(VoxelHash{}(voxel)) * 0x9E3779B97F4A7C15ull) >> shift);
}

/// The nearest map point to a query and its squared distance.
struct Neighbor {
  Eigen::Vector3d point = Eigen::Vector3d::Zero();  ///< the map point, in the map frame
  double squared_distance = 0.0;                    ///< m^2, from the query
};

/// A sparse voxel map of points in one frame (the odometry or a keyframe frame).
class VoxelHashMap {
 public:
  /// A map of voxels of edge `voxel_size` (m) holding at most `max_points_per_voxel` points each.
  VoxelHashMap(double voxel_size, int max_points_per_voxel);

  /// Adds points already in the map frame; a voxel that is full ignores new points.
  void addPoints(std::span<const Eigen::Vector3d> points);

  /// Adds points given in a sensor frame, mapped by `T_map_sensor` first.
  void addPoints(std::span<const Eigen::Vector3d> points, const Eigen::Isometry3d& T_map_sensor);

  /// Removes every voxel whose first point is farther than `max_distance` (m) from `position`.
  void removeFarFrom(const Eigen::Vector3d& position, double max_distance);

  /// Removes the points within `radius` (m) of `position` (voxels whose first
  /// point is) for which `remove(point)` is true; returns how many went.
  template <class Predicate>
  std::size_t removeNear(const Eigen::Vector3d& position, double radius, Predicate&& remove) {
    const double radius2 = radius * radius;
    std::size_t removed = 0;
    for (std::uint32_t block = 0; block < counts_.size(); ++block) {
      if (counts_[block] == 0 || (first(block) - position).squaredNorm() > radius2) continue;
      // In place, the survivors keep their order.
      const std::span<Eigen::Vector3d> points = pointsOf(block);
      const auto kept = std::remove_if(points.begin(), points.end(), remove);
      const auto gone = static_cast<std::size_t>(points.end() - kept);
      removed += gone;
      counts_[block] -= static_cast<std::uint32_t>(gone);
      if (counts_[block] == 0) releaseBlock(block);
    }
    return removed;
  }

  /// The nearest map point to `query` among the 27 voxels around it (none when they are empty).
  [[nodiscard]] std::optional<Neighbor> nearest(const Eigen::Vector3d& query) const;

  /// Up to `max_count` map points nearest to `query` among the 27 voxels around it,
  /// closest first (for local surface normals).
  [[nodiscard]] std::vector<Eigen::Vector3d> neighbors(const Eigen::Vector3d& query,
                                                       std::size_t max_count) const;

  /// Calls `visit(point)` for every map point in the 27 voxels around `query`
  /// (the candidates of a nearest-neighbour or local-normal search).
  template <class Visit>
  void forEachPointNear(const Eigen::Vector3d& query, Visit&& visit) const {
    const Voxel center = voxelOf(query, voxel_size_);
    for (int dx = -1; dx <= 1; ++dx) {
      for (int dy = -1; dy <= 1; ++dy) {
        for (int dz = -1; dz <= 1; ++dz) {
          const std::uint32_t block = find(center + Voxel(dx, dy, dz));
          if (block == kNone) continue;
          for (const Eigen::Vector3d& point : pointsOf(block)) visit(point);
        }
      }
    }
  }

  /// Every point of the map, voxel by voxel.
  [[nodiscard]] std::vector<Eigen::Vector3d> pointCloud() const;

  /// Removes every point.
  void clear();

  /// True when the map holds no point.
  [[nodiscard]] bool empty() const { return size() == 0; }

  /// The number of occupied voxels.
  [[nodiscard]] std::size_t size() const { return counts_.size() - free_.size(); }

  /// The number of points over all voxels.
  [[nodiscard]] std::size_t pointCount() const;

  /// m, the voxel edge.
  [[nodiscard]] double voxelSize() const { return voxel_size_; }

  /// The most points a voxel keeps.
  [[nodiscard]] int maxPointsPerVoxel() const { return max_points_per_voxel_; }

 private:
  // An open-addressing table (linear probing, at most half full) from a
  // voxel to its block: a fixed run of max_points_per_voxel_ points in one
  // array. A search of the 27 voxels around a point, the registration's
  // inner loop, then reads a slot and a block per voxel instead of
  // following a hash node to a vector of its own: the table and the points
  // are each one contiguous allocation.
  static constexpr std::uint32_t kNone = 0xffffffffu;
  struct Slot {
    Voxel key = Voxel::Zero();
    std::uint32_t block = kNone;  ///< kNone: an empty slot
  };

  /// The block of `voxel`, or kNone.
  [[nodiscard]] std::uint32_t find(const Voxel& voxel) const {
    if (slots_.empty()) return kNone;
    for (std::size_t i = home(voxel);; i = (i + 1) & (slots_.size() - 1)) {
      const Slot& slot = slots_[i];
      if (slot.block == kNone) return kNone;
      if (slot.key == voxel) return slot.block;
    }
  }
  /// The slot where a search for `voxel` starts.
  [[nodiscard]] std::size_t home(const Voxel& voxel) const { return voxelSlot(voxel, shift_); }
  /// The block of `voxel`, a new empty one when it has none.
  std::uint32_t findOrAdd(const Voxel& voxel);
  /// Puts `block` (of key keys_[block]) into the table, which has room.
  void insertSlot(std::uint32_t block);
  /// Frees `block`, empty now, and takes its voxel out of the table.
  void releaseBlock(std::uint32_t block);
  /// The table at `slots` slots (a power of two), every block re-entered.
  void rehash(std::size_t slots);

  [[nodiscard]] std::span<Eigen::Vector3d> pointsOf(std::uint32_t block) {
    return {points_.data() + std::size_t{block} * stride_, counts_[block]};
  }
  [[nodiscard]] std::span<const Eigen::Vector3d> pointsOf(std::uint32_t block) const {
    return {points_.data() + std::size_t{block} * stride_, counts_[block]};
  }
  [[nodiscard]] const Eigen::Vector3d& first(std::uint32_t block) const {
    return points_[std::size_t{block} * stride_];
  }

  double voxel_size_;
  int max_points_per_voxel_;
  std::size_t stride_;                   ///< points per block
  std::vector<Slot> slots_;              ///< the table, a power of two long (or empty)
  int shift_ = 64;                       ///< 64 - log2(slots_.size())
  std::vector<Voxel> keys_;              ///< each block's voxel
  std::vector<std::uint32_t> counts_;    ///< each block's points (0: a free block)
  std::vector<Eigen::Vector3d> points_;  ///< the blocks, stride_ points each
  std::vector<std::uint32_t> free_;      ///< blocks to reuse
};

}  // namespace dcl::odometry
