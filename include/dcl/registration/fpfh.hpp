#pragma once

/// Fast Point Feature Histograms (Rusu, Blodow, Beetz 2009), the local
/// features behind the global registration that takes over when the yaw from
/// place recognition does not lead ICP to the loop: for each pair of a point
/// and a neighbour, three angles of the Darboux frame of their normals are
/// binned (11 bins each, the simplified point feature histogram, SPFH), then a
/// point's SPFH is blended with its neighbours' weighted by inverse distance.
/// The histograms depend only on the local surface, not on the frame, so
/// features of two scans of one place match whatever their relative pose.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include <dcl/registration/gicp.hpp>

namespace dcl::registration {

/// 33 bins: angle phi (11), alpha (11), theta (11), each part summing to 100
/// (all zero for a point without usable neighbours).
using FpfhFeature = Eigen::Matrix<float, 33, 1>;

/// How features are computed.
struct FpfhConfig {
  /// m, neighbourhood of a feature; about five times the spacing of the points
  /// (the features are computed on a cloud voxel-filtered at about 1 m).
  double radius = 5.0;
  /// Neighbours used at most (the nearest ones), bounding the cost in dense areas.
  std::size_t max_neighbors = 64;

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("radius", radius, "m, neighbourhood of a feature (about 5 point spacings)").positive();
    // A feature needs three neighbours; a search returns PointTree::kMaxNeighbors at most.
    v.field("max_neighbors", max_neighbors, "nearest neighbours used at most")
        .within(3, PointTree::kMaxNeighbors);
  }
};

/// The FPFH of every point of `cloud`, with the cloud's normals (oriented
/// towards its sensor). Points with fewer than three neighbours get a zero feature.
std::vector<FpfhFeature> computeFpfh(RegistrationCloud& cloud, const FpfhConfig& config = {});

/// A putative pair: a source point and a target point with similar features.
struct Correspondence {
  std::uint32_t source = 0;  ///< index into the source cloud
  std::uint32_t target = 0;  ///< index into the target cloud
};

/// Mutual nearest neighbours in feature space (a 33-D kd-tree each way): a pair
/// is kept only when each feature is the other's nearest, which discards most
/// of the ambiguous matches of repetitive structure before RANSAC sees them.
/// Zero features match nothing. The searches are approximate: a neighbour
/// within (1 + `approximation`) times the nearest distance may be returned
/// (nanoflann's eps); the mutual test drops the pairs this spoils, and on
/// KITTI 00 the default halves the time with as many correct pairs.
std::vector<Correspondence> matchFeatures(const std::vector<FpfhFeature>& source,
                                          const std::vector<FpfhFeature>& target,
                                          double approximation = 2.0);

}  // namespace dcl::registration
