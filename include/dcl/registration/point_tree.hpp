#pragma once

/// A static kd-tree over 3-D points (nanoflann), the one spatial index of the
/// registration module: nearest neighbours for ICP correspondences, k nearest
/// for local surface shapes, radius searches for FPFH.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <optional>
#include <vector>

namespace dcl::registration {

/// A point found by a search: its index in the tree's points and its squared distance (m^2).
struct Neighbor {
  std::uint32_t index = 0;
  double squared_distance = 0.0;
};

/// The kd-tree owns its points; it is built once and never changes, so that
/// searches are plain const calls that may run from several threads.
class PointTree {
 public:
  /// Most neighbours a k-nearest search returns.
  static constexpr std::size_t kMaxNeighbors = 64;

  /// Builds the tree over `points` (fewer than 2^32 of them).
  explicit PointTree(std::vector<Eigen::Vector3d> points = {});
  ~PointTree();
  PointTree(PointTree&& other) noexcept;
  PointTree& operator=(PointTree&& other) noexcept;
  PointTree(const PointTree&) = delete;
  PointTree& operator=(const PointTree&) = delete;

  [[nodiscard]] const std::vector<Eigen::Vector3d>& points() const;
  [[nodiscard]] std::size_t size() const { return points().size(); }
  [[nodiscard]] bool empty() const { return points().empty(); }

  /// The nearest point closer than `max_distance` (m); none when there is none.
  [[nodiscard]] std::optional<Neighbor> nearest(const Eigen::Vector3d& query,
                                                double max_distance) const;

  /// The `k` (at most kMaxNeighbors) nearest points closer than `max_distance`,
  /// closest first, into `out` (resized to what was found).
  void nearest(const Eigen::Vector3d& query, std::size_t k, double max_distance,
               std::vector<Neighbor>& out) const;

  /// Every point closer than `radius` (m), in no particular order, into `out`.
  void within(const Eigen::Vector3d& query, double radius, std::vector<Neighbor>& out) const;

 private:
  struct Index;
  std::unique_ptr<Index> index_;
};

}  // namespace dcl::registration
