#pragma once
// How far one voxel map lies from another: the median distance of its points
// to the local planes of the other (its 8 nearest points within 1 m), over the
// points where the two overlap. Distances along a surface, which voxel grids
// of slightly shifted clouds always differ by, do not count; distances across
// it (a map blurred by a wrong pose) do.
#include <Eigen/Eigenvalues>
#include <algorithm>
#include <cmath>
#include <vector>

#include <dcl/registration/point_tree.hpp>
#include <dcl/swarm/merged_map.hpp>

namespace dcl::test {

struct MapDistance {
  double median = 0.0;     ///< m
  std::size_t points = 0;  ///< points of the map with enough of the reference around
};

inline MapDistance mapDistance(const swarm::VoxelMap& map, const swarm::VoxelMap& reference) {
  std::vector<Eigen::Vector3d> points;
  for (const Eigen::Vector3f& p : reference.points) points.push_back(p.cast<double>());
  const registration::PointTree tree(std::move(points));
  std::vector<double> distances;
  std::vector<registration::Neighbor> near;
  for (const Eigen::Vector3f& p : map.points) {
    const Eigen::Vector3d q = p.cast<double>();
    tree.nearest(q, 8, 1.0, near);
    if (near.size() < 6) continue;
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const registration::Neighbor& n : near) mean += tree.points()[n.index];
    mean /= static_cast<double>(near.size());
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
    for (const registration::Neighbor& n : near) {
      const Eigen::Vector3d d = tree.points()[n.index] - mean;
      covariance += d * d.transpose();
    }
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eigen(covariance);
    distances.push_back(std::abs(eigen.eigenvectors().col(0).dot(q - mean)));
  }
  if (distances.empty()) return {};
  const auto middle = distances.begin() + static_cast<std::ptrdiff_t>(distances.size() / 2);
  std::nth_element(distances.begin(), middle, distances.end());
  return {*middle, distances.size()};
}

}  // namespace dcl::test
