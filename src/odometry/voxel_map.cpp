#include <algorithm>
#include <bit>
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
    : voxel_size_(voxel_size),
      max_points_per_voxel_(std::max(1, max_points_per_voxel)),
      stride_(static_cast<std::size_t>(max_points_per_voxel_)) {}

void VoxelHashMap::clear() {
  slots_.clear();
  shift_ = 64;
  keys_.clear();
  counts_.clear();
  points_.clear();
  free_.clear();
}

void VoxelHashMap::insertSlot(std::uint32_t block) {
  std::size_t i = home(keys_[block]);
  while (slots_[i].block != kNone) i = (i + 1) & (slots_.size() - 1);
  slots_[i] = Slot{keys_[block], block};
}

void VoxelHashMap::rehash(std::size_t slots) {
  slots_.assign(slots, Slot{});
  shift_ = 64 - std::countr_zero(slots);
  for (std::uint32_t block = 0; block < counts_.size(); ++block) {
    if (counts_[block] > 0) insertSlot(block);
  }
}

std::uint32_t VoxelHashMap::findOrAdd(const Voxel& voxel) {
  if (const std::uint32_t block = find(voxel); block != kNone) return block;
  if (2 * (size() + 1) > slots_.size()) rehash(std::max<std::size_t>(64, 2 * slots_.size()));
  std::uint32_t block = 0;
  if (!free_.empty()) {
    block = free_.back();
    free_.pop_back();
    keys_[block] = voxel;
  } else {
    block = static_cast<std::uint32_t>(counts_.size());
    keys_.push_back(voxel);
    counts_.push_back(0);
    points_.resize(points_.size() + stride_);
  }
  insertSlot(block);
  return block;
}

void VoxelHashMap::releaseBlock(std::uint32_t block) {
  counts_[block] = 0;
  free_.push_back(block);
  // Backward-shift deletion: each entry after the hole that may sit in it
  // (its home is not between the hole and itself) moves into it.
  const std::size_t mask = slots_.size() - 1;
  std::size_t hole = home(keys_[block]);
  while (slots_[hole].block != block) hole = (hole + 1) & mask;
  for (std::size_t i = (hole + 1) & mask; slots_[i].block != kNone; i = (i + 1) & mask) {
    const std::size_t wanted = home(slots_[i].key);
    if (((i - wanted) & mask) >= ((i - hole) & mask)) {
      slots_[hole] = slots_[i];
      hole = i;
    }
  }
  slots_[hole] = Slot{};
}

void VoxelHashMap::addPoints(std::span<const Eigen::Vector3d> points) {
  // Points of one voxel are kept at least this far apart, so a voxel's budget
  // spreads over its volume instead of piling up where the sensor dwells.
  const double min_spacing = voxel_size_ / std::sqrt(static_cast<double>(max_points_per_voxel_));
  const double min_spacing2 = min_spacing * min_spacing;
  for (const Eigen::Vector3d& point : points) {
    const std::uint32_t block = findOrAdd(voxelOf(point, voxel_size_));
    const std::span<const Eigen::Vector3d> held = pointsOf(block);
    if (held.size() >= stride_) continue;
    const bool crowded = std::any_of(held.begin(), held.end(), [&](const Eigen::Vector3d& p) {
      return (p - point).squaredNorm() < min_spacing2;
    });
    if (crowded) continue;
    points_[std::size_t{block} * stride_ + counts_[block]++] = point;
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
  for (std::uint32_t block = 0; block < counts_.size(); ++block) {
    if (counts_[block] > 0 && (first(block) - position).squaredNorm() > max_distance2)
      releaseBlock(block);
  }
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
  for (std::uint32_t block = 0; block < counts_.size(); ++block) {
    const std::span<const Eigen::Vector3d> held = pointsOf(block);
    points.insert(points.end(), held.begin(), held.end());
  }
  return points;
}

std::size_t VoxelHashMap::pointCount() const {
  std::size_t count = 0;
  for (const std::uint32_t n : counts_) count += n;
  return count;
}

}  // namespace dcl::odometry
