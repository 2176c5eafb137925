#pragma once

/// RANSAC over feature correspondences: the global registration that needs no
/// initial guess. A hypothesis is the rigid transform of three correspondences
/// (closed form, Umeyama); samples whose triangles differ in shape between the
/// two clouds are dropped before any scoring (the edge-length "tuple" test of
/// Zhou et al. 2016), which removes most outlier samples for the cost of three
/// distances; a hypothesis scores the correspondences it explains. The seed is
/// fixed, so a run is reproducible.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <cstdint>
#include <span>

#include <dcl/core/config.hpp>
#include <dcl/registration/fpfh.hpp>

namespace dcl::registration {

/// How RANSAC samples and scores.
struct RansacConfig {
  static constexpr int kMaxIterations = 10'000'000;  ///< samples at most (seconds of work each 1e6)

  int max_iterations = 100000;   ///< samples drawn at most
  double inlier_distance = 1.5;  ///< m, a correspondence is explained within this distance
  /// Shortest over longest of each pair of matching triangle edges, at least.
  double edge_similarity = 0.9;
  /// Stop once this sure that no better hypothesis is left (from the best inlier ratio).
  double confidence = 0.9999;
  std::size_t min_inliers = 8;  ///< fewer explained correspondences: nothing found
  std::uint64_t seed = 1;       ///< random generator seed (runs are reproducible)

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("max_iterations", max_iterations, "samples drawn at most").within(1, kMaxIterations);
    v.field("inlier_distance", inlier_distance, "m, a correspondence is explained within this")
        .positive();
    v.field("edge_similarity", edge_similarity,
            "shortest/longest of matching triangle edges, at least")
        .within(0.0, 1.0, core::Interval::open_low);
    v.field("confidence", confidence, "stop once this sure no better hypothesis is left")
        .within(0.0, 1.0, core::Interval::open);
    // A rigid transform needs three correspondences.
    v.field("min_inliers", min_inliers, "fewest explained correspondences for a result").atLeast(3);
    v.field("seed", seed, "random generator seed");
  }
};

/// The best hypothesis, refitted to all the correspondences it explains.
struct RansacResult {
  Eigen::Isometry3d T_target_source = Eigen::Isometry3d::Identity();
  bool found = false;       ///< at least min_inliers correspondences explained
  std::size_t inliers = 0;  ///< correspondences explained by T_target_source
  int iterations = 0;       ///< samples drawn
};

/// Estimates T_target_source from `correspondences` between `source` and
/// `target` points. Never throws: fewer than three correspondences, or indices
/// out of range (which are ignored), give found = false.
RansacResult ransacRegistration(std::span<const Eigen::Vector3d> source,
                                std::span<const Eigen::Vector3d> target,
                                std::span<const Correspondence> correspondences,
                                const RansacConfig& config = {});

}  // namespace dcl::registration
