#pragma once

/// The local map of the LiDAR odometry: a hash of integer voxel coordinates to
/// a few points each (KISS-ICP's VoxelHashMap, Vizzo et al. 2023). Bounded
/// points per voxel keep the map sparse and uniform; culling by distance keeps
/// it local, so memory and search cost do not grow with the trajectory.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstddef>
#include <iterator>
#include <optional>
#include <span>
#include <unordered_map>
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
    for (auto it = voxels_.begin(); it != voxels_.end();) {
      VoxelPoints& points = it->second;
      if (!points.empty() && (points.front() - position).squaredNorm() <= radius2) {
        removed += static_cast<std::size_t>(std::erase_if(points, remove));
      }
      it = points.empty() ? voxels_.erase(it) : std::next(it);
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
          const auto it = voxels_.find(center + Voxel(dx, dy, dz));
          if (it == voxels_.end()) continue;
          for (const Eigen::Vector3d& point : it->second) visit(point);
        }
      }
    }
  }

  /// Every point of the map, voxel by voxel.
  [[nodiscard]] std::vector<Eigen::Vector3d> pointCloud() const;

  /// Removes every point.
  void clear() { voxels_.clear(); }

  /// True when the map holds no point.
  [[nodiscard]] bool empty() const { return voxels_.empty(); }

  /// The number of occupied voxels.
  [[nodiscard]] std::size_t size() const { return voxels_.size(); }

  /// The number of points over all voxels.
  [[nodiscard]] std::size_t pointCount() const;

  /// m, the voxel edge.
  [[nodiscard]] double voxelSize() const { return voxel_size_; }

  /// The most points a voxel keeps.
  [[nodiscard]] int maxPointsPerVoxel() const { return max_points_per_voxel_; }

 private:
  /// The points of one voxel (a small vector: at most max_points_per_voxel_).
  using VoxelPoints = std::vector<Eigen::Vector3d>;

  double voxel_size_;
  int max_points_per_voxel_;
  std::unordered_map<Voxel, VoxelPoints, VoxelHash> voxels_;
};

}  // namespace dcl::odometry
