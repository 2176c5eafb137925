#include <algorithm>
#include <cmath>
#include <cstdint>

#include <dcl/odometry/voxel_map.hpp>

namespace dcl::odometry {

Voxel voxelOf(const Eigen::Vector3d& point, double voxel_size) {
  return Voxel(static_cast<int>(std::floor(point.x() / voxel_size)),
               static_cast<int>(std::floor(point.y() / voxel_size)),
               static_cast<int>(std::floor(point.z() / voxel_size)));
}

std::size_t VoxelHash::operator()(const Voxel& voxel) const noexcept {
  // Teschner et al. 2003, "Optimized Spatial Hashing for Collision Detection".
  const auto x = static_cast<std::uint32_t>(voxel.x());
  const auto y = static_cast<std::uint32_t>(voxel.y());
  const auto z = static_cast<std::uint32_t>(voxel.z());
  return static_cast<std::size_t>((x * 73856093u) ^ (y * 19349669u) ^ (z * 83492791u));
}

VoxelHashMap::VoxelHashMap(double voxel_size, int max_points_per_voxel)
    : voxel_size_(voxel_size), max_points_per_voxel_(std::max(1, max_points_per_voxel)) {}

void VoxelHashMap::addPoints(std::span<const Eigen::Vector3d> points) {
  // Points of one voxel are kept at least this far apart, so a voxel's budget
  // spreads over its volume instead of piling up where the sensor dwells.
  const double min_spacing = voxel_size_ / std::sqrt(static_cast<double>(max_points_per_voxel_));
  const double min_spacing2 = min_spacing * min_spacing;
  const auto max_points = static_cast<std::size_t>(max_points_per_voxel_);
  for (const Eigen::Vector3d& point : points) {
    VoxelPoints& voxel = voxels_[voxelOf(point, voxel_size_)];
    if (voxel.size() >= max_points) continue;
    const bool crowded = std::any_of(voxel.begin(), voxel.end(), [&](const Eigen::Vector3d& p) {
      return (p - point).squaredNorm() < min_spacing2;
    });
    if (crowded) continue;
    if (voxel.empty()) voxel.reserve(max_points);
    voxel.push_back(point);
  }
}

void VoxelHashMap::addPoints(std::span<const Eigen::Vector3d> points,
                             const Eigen::Isometry3d& T_map_sensor) {
  std::vector<Eigen::Vector3d> mapped(points.size());
  std::transform(points.begin(), points.end(), mapped.begin(),
                 [&](const Eigen::Vector3d& p) { return T_map_sensor * p; });
  addPoints(mapped);
}

void VoxelHashMap::removeFarFrom(const Eigen::Vector3d& position, double max_distance) {
  const double max_distance2 = max_distance * max_distance;
  std::erase_if(voxels_, [&](const auto& entry) {
    return entry.second.empty() || (entry.second.front() - position).squaredNorm() > max_distance2;
  });
}

std::optional<Neighbor> VoxelHashMap::nearest(const Eigen::Vector3d& query) const {
  std::optional<Neighbor> best;
  forEachPointNear(query, [&](const Eigen::Vector3d& point) {
    const double d2 = (point - query).squaredNorm();
    if (!best || d2 < best->squared_distance) best = Neighbor{point, d2};
  });
  return best;
}

std::vector<Eigen::Vector3d> VoxelHashMap::neighbors(const Eigen::Vector3d& query,
                                                     std::size_t max_count) const {
  std::vector<Neighbor> candidates;
  forEachPointNear(query, [&](const Eigen::Vector3d& point) {
    candidates.push_back({point, (point - query).squaredNorm()});
  });
  const std::size_t count = std::min(max_count, candidates.size());
  std::partial_sort(
      candidates.begin(), candidates.begin() + static_cast<std::ptrdiff_t>(count), candidates.end(),
      [](const Neighbor& a, const Neighbor& b) { return a.squared_distance < b.squared_distance; });
  std::vector<Eigen::Vector3d> result(count);
  for (std::size_t i = 0; i < count; ++i) result[i] = candidates[i].point;
  return result;
}

std::vector<Eigen::Vector3d> VoxelHashMap::pointCloud() const {
  std::vector<Eigen::Vector3d> points;
  points.reserve(pointCount());
  for (const auto& [voxel, voxel_points] : voxels_) {
    points.insert(points.end(), voxel_points.begin(), voxel_points.end());
  }
  return points;
}

std::size_t VoxelHashMap::pointCount() const {
  std::size_t count = 0;
  for (const auto& entry : voxels_) count += entry.second.size();
  return count;
}

}  // namespace dcl::odometry
