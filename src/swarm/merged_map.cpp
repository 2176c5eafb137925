#include <cmath>
#include <limits>
#include <string>

#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>
#include <dcl/registration/cloud_codec.hpp>
#include <dcl/registration/voxel_filter.hpp>
#include <dcl/swarm/merged_map.hpp>

namespace dcl::swarm {
namespace {

/// zstd level of the kept clouds: level 3 is within 2 % of level 15's size at
/// a third less time (registration/cloud_codec.hpp), and a run keeps every keyframe.
constexpr int kZstdLevel = 3;
/// Quantisation step of the kept clouds, per metre of voxel: 2 cm at 0.4 m,
/// an error of at most a fortieth of a voxel an axis.
constexpr double kStepPerVoxel = 0.05;

/// Weighted point sums per voxel in an open-addressing table (linear
/// probing) that doubles when half full. A map has millions of voxels, so the
/// table holds only cell numbers, and a cell only what the result needs: its
/// voxel, the sum of the points' offsets from the voxel's corner in float
/// (small numbers, exact enough), the weight, and the robot with the heaviest
/// single contribution. The simulated KITTI 05 (1.2 million voxels) merges in
/// about 60 MB.
class VoxelGrid {
 public:
  /// A grid of voxel edge `voxel` expecting about `cells` occupied voxels.
  VoxelGrid(double voxel, std::size_t cells) : voxel_(voxel), inverse_voxel_(1.0 / voxel) {
    cells_.reserve(cells);
    std::size_t size = 1024;
    while (size < 2 * cells) size *= 2;
    table_.assign(size, kNone);
  }

  /// Adds `weight` points at `p`; a point not finite or beyond 2^20 voxels is skipped.
  void add(const Eigen::Vector3d& p, std::uint32_t weight, std::uint8_t robot) {
    const std::uint64_t key = registration::voxelKey(p, inverse_voxel_);
    if (key == registration::kNoVoxel) return;
    Cell& c = cell(key);
    c.sum +=
        ((p - registration::voxelCorner(key, voxel_)) * static_cast<double>(weight)).cast<float>();
    c.weight += weight;
    if (weight > c.robot_weight) {
      c.robot_weight = weight;
      c.robot = robot;
    }
  }

  /// The centroids, in order of first appearance.
  [[nodiscard]] VoxelMap map() const {
    VoxelMap m;
    m.points.reserve(cells_.size());
    m.weights.reserve(cells_.size());
    m.robots.reserve(cells_.size());
    for (const Cell& c : cells_) {
      m.points.push_back(
          (registration::voxelCorner(c.key, voxel_) + c.sum.cast<double>() / c.weight)
              .cast<float>());
      m.weights.push_back(c.weight);
      m.robots.push_back(c.robot);
    }
    return m;
  }

 private:
  static constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();

  struct Cell {
    std::uint64_t key = 0;
    Eigen::Vector3f sum = Eigen::Vector3f::Zero();
    std::uint32_t weight = 0;
    std::uint32_t robot_weight = 0;
    std::uint8_t robot = 0;
  };

  Cell& cell(std::uint64_t key) {
    std::size_t i = find(key);
    if (table_[i] == kNone) {
      if (2 * (cells_.size() + 1) > table_.size()) {
        grow();
        i = find(key);
      }
      table_[i] = static_cast<std::uint32_t>(cells_.size());
      cells_.push_back({key});
    }
    return cells_[table_[i]];
  }

  /// The table slot of `key`'s cell, or the empty slot where it goes.
  [[nodiscard]] std::size_t find(std::uint64_t key) const {
    const std::size_t mask = table_.size() - 1;
    std::size_t i = registration::hashVoxelKey(key) & mask;
    while (table_[i] != kNone && cells_[table_[i]].key != key) i = (i + 1) & mask;
    return i;
  }

  void grow() {
    table_.assign(2 * table_.size(), kNone);
    for (std::size_t c = 0; c < cells_.size(); ++c)
      table_[find(cells_[c].key)] = static_cast<std::uint32_t>(c);
  }

  double voxel_;
  double inverse_voxel_;
  std::vector<std::uint32_t> table_;  ///< cell numbers, kNone where empty
  std::vector<Cell> cells_;
};

}  // namespace

void validate(const MapConfig& config) {
  core::checkConfig(config, "map config");
}

KeyframeClouds::KeyframeClouds(double voxel) : voxel_(voxel) {
  validate(MapConfig{voxel});
}

void KeyframeClouds::add(const core::PointCloud& cloud) {
  if (voxel_ == 0.0) return;
  registration::CloudCodecConfig codec;
  codec.voxel_size = voxel_;
  codec.resolution = kStepPerVoxel * voxel_;
  codec.zstd_level = kZstdLevel;
  clouds_.push_back(registration::encodeVerificationCloud(cloud, codec));
  bytes_ += clouds_.back().size();
}

core::PointCloud KeyframeClouds::cloud(std::size_t k) const {
  if (k >= clouds_.size())
    throw core::Error("keyframe clouds: no cloud " + std::to_string(k) + " of " +
                      std::to_string(clouds_.size()));
  return registration::decodeVerificationCloud(clouds_[k]);
}

VoxelMap robotMap(const KeyframeClouds& clouds, std::span<const Eigen::Isometry3d> T_world_keyframe,
                  std::uint8_t robot) {
  if (T_world_keyframe.size() != clouds.size())
    throw core::Error("robot map: " + std::to_string(T_world_keyframe.size()) + " poses for " +
                      std::to_string(clouds.size()) + " keyframe clouds");
  if (clouds.size() == 0) return {};
  VoxelGrid grid(clouds.voxel(), 0);
  for (std::size_t k = 0; k < clouds.size(); ++k) {
    for (const Eigen::Vector3f& p : clouds.cloud(k).points)
      grid.add(T_world_keyframe[k] * p.cast<double>(), 1, robot);
  }
  return grid.map();
}

VoxelMap mergeMaps(std::span<const VoxelMap> maps, double voxel) {
  if (!(voxel > 0.0) || !std::isfinite(voxel))
    throw core::Error("merged map: the voxel must be a finite number > 0");
  std::size_t points = 0;
  for (const VoxelMap& m : maps) points += m.size();
  VoxelGrid grid(voxel, points);  // at most one cell a point
  for (const VoxelMap& m : maps) {
    for (std::size_t i = 0; i < m.size(); ++i)
      grid.add(m.points[i].cast<double>(), m.weights[i], m.robots[i]);
  }
  return grid.map();
}

}  // namespace dcl::swarm
