#pragma once

/// The built-in intra-robot loop closure, for odometry that has none (paper
/// §III-A): for each new keyframe, find earlier keyframes of the same robot
/// that may show the same place (excluding the most recent ones, which trivially
/// do), verify each geometrically by ICP of the new keyframe's cloud against a
/// submap of the candidate's neighbours, and emit the first that passes as an
/// intra-robot loop factor.
///
/// The candidate search is an interface: a radius search on the keyframes'
/// current position estimates stands in until the LiDAR-Iris place index lands.

#include <Eigen/Geometry>
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include <dcl/core/config.hpp>
#include <dcl/core/keyframe.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/odometry/registration.hpp>

namespace dcl::odometry {

/// A keyframe that may show the same place as the query.
struct LoopCandidate {
  core::KeyframeId keyframe;  ///< the earlier keyframe
  double score = 0.0;         ///< lower is better (the radius search: distance in metres)
};

/// Where loop candidates come from (a radius search on poses, later LiDAR-Iris).
class LoopCandidateSearch {
 public:
  virtual ~LoopCandidateSearch() = default;

  /// Indexes the robot's next keyframe (ids 0, 1, 2, ... in order).
  virtual void add(const core::Keyframe& keyframe) = 0;

  /// Candidates for `query` among the first `searchable` keyframes indexed, best
  /// first. `T_world_keyframes[i]` is the current estimate of keyframe i, the
  /// query's included, for searches that use positions (descriptors ignore them).
  [[nodiscard]] virtual std::vector<LoopCandidate> search(
      const core::Keyframe& query, std::span<const Eigen::Isometry3d> T_world_keyframes,
      std::size_t searchable) const = 0;
};

/// Settings of the radius search.
struct RadiusSearchConfig {
  double radius = 10.0;            ///< m, candidates lie this close to the query's estimate
  std::size_t max_candidates = 3;  ///< the nearest few are verified, nearest first

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("radius", radius, "m, candidates lie this close to the query's position estimate")
        .positive();
    v.field("max_candidates", max_candidates, "the nearest few candidates are verified").positive();
  }
};

/// Candidates by distance between position estimates: works while the drift
/// since the place was last seen stays below the radius.
class RadiusCandidateSearch final : public LoopCandidateSearch {
 public:
  /// A search with `config`.
  explicit RadiusCandidateSearch(const RadiusSearchConfig& config = {}) : config_(config) {}

  /// Nothing to index: the search reads the estimates it is given.
  void add(const core::Keyframe& /*keyframe*/) override {}

  /// The nearest `max_candidates` keyframes within `radius` of the query's estimate.
  [[nodiscard]] std::vector<LoopCandidate> search(
      const core::Keyframe& query, std::span<const Eigen::Isometry3d> T_world_keyframes,
      std::size_t searchable) const override;

 private:
  RadiusSearchConfig config_;
};

/// How candidates are excluded and verified.
struct LoopClosureConfig {
  static constexpr int kMaxPointsPerVoxel = 1000;  ///< a submap voxel's budget at most

  RadiusSearchConfig search{};  ///< the default candidate search
  /// Keyframes this recent are never candidates (with 1 m keyframes, the last 50 m).
  std::size_t exclude_recent = 50;
  double exclude_seconds = 30.0;  ///< s, nor keyframes younger than this
  /// Keyframes skipped after an accepted loop: the next ones along a revisit add
  /// little that the loop did not, and each costs a verification and a solve.
  std::size_t skip_after_loop = 4;
  int submap_neighbors = 10;       ///< the submap holds the candidate and +/- this many (paper: 10)
  double map_voxel_size = 1.0;     ///< m, voxel edge of the submap (KISS-ICP's for HDL-64 maps)
  int max_points_per_voxel = 20;   ///< points a submap voxel keeps (KISS-ICP: 20)
  double source_voxel_size = 1.0;  ///< m, the query cloud is thinned to this for ICP (speed)
  /// m, ICP correspondence distances, coarse to fine: the guess from drifted
  /// odometry can be metres off, the last stage measures the fit.
  std::vector<double> icp_distances = {3.0, 1.0, 0.3};
  int icp_iterations = 30;  ///< Gauss-Newton iterations at most per stage
  /// Fewest share of the query's points within the last distance of the submap
  /// (the paper's 0.3 m inlier test, as a share so that it scales with the sensor).
  double min_inlier_share = 0.5;
  double max_rmse = 0.15;  ///< m, largest RMS residual of those inliers
  /// m^2 and rad^2, floor of the loop's covariance: ICP's own information grows with
  /// the number of points and would make a loop stiffer than any odometry factor.
  double min_variance = 1e-4;

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.section("search", search, "the radius search on position estimates");
    v.field("exclude_recent", exclude_recent, "the most recent keyframes are never candidates");
    v.field("exclude_seconds", exclude_seconds, "s, nor keyframes younger than this").nonNegative();
    v.field("skip_after_loop", skip_after_loop, "keyframes not searched after an accepted loop");
    v.field("submap_neighbors", submap_neighbors, "submap: candidate +/- this many keyframes")
        .nonNegative();
    v.field("map_voxel_size", map_voxel_size, "m, submap voxel edge")
        .within(core::kMinVoxelEdge, core::kMaxVoxelEdge);
    v.field("max_points_per_voxel", max_points_per_voxel, "points a submap voxel keeps")
        .within(1, kMaxPointsPerVoxel);
    v.field("source_voxel_size", source_voxel_size, "m, query cloud thinning for ICP")
        .within(core::kMinVoxelEdge, core::kMaxVoxelEdge);
    // The last stage's distance measures the fit: without one there is no loop.
    v.field("icp_distances", icp_distances, "m, ICP correspondence distances, coarse to fine")
        .rule(!icp_distances.empty() &&
                  std::ranges::all_of(icp_distances,
                                      [](double d) { return d > 0.0 && std::isfinite(d); }),
              "must hold at least one distance, each positive and finite");
    v.field("icp_iterations", icp_iterations, "Gauss-Newton iterations at most per stage")
        .positive();
    v.field("min_inlier_share", min_inlier_share, "fewest share of query points that fit")
        .within(0.0, 1.0);
    v.field("max_rmse", max_rmse, "m, largest RMS residual of the fitting points").positive();
    v.field("min_variance", min_variance, "floor of the loop covariance's variances").positive();
  }
};

/// An accepted intra-robot loop: the relative pose of the query keyframe in the
/// candidate's frame (the factor's from = candidate, to = query).
struct IntraLoop {
  core::KeyframeId from;  ///< the earlier keyframe (the candidate)
  core::KeyframeId to;    ///< the new keyframe (the query)
  Eigen::Isometry3d T_from_to = Eigen::Isometry3d::Identity();  ///< the registered relative pose
  core::Matrix6d information = core::Matrix6d::Identity();      ///< over [rho; phi]
  double inlier_share = 0.0;  ///< share of the query's points that fit the submap
  double rmse = 0.0;          ///< m, RMS residual of those points
};

/// The outcome of verifying one candidate.
struct LoopVerification {
  std::optional<IntraLoop> loop;    ///< the loop when accepted
  std::string rejection;            ///< why not, when rejected; empty when accepted
  RegistrationResult registration;  ///< the last ICP stage
  double inlier_share = 0.0;        ///< share of the query's points that fit the submap
};

/// Counts of what the loop closure did.
struct LoopClosureStats {
  std::size_t queries = 0;     ///< keyframes searched
  std::size_t candidates = 0;  ///< candidates verified
  std::size_t accepted = 0;    ///< loops accepted
  std::size_t rejected = 0;    ///< candidates rejected by verification
};

/// Candidate search plus geometric verification over one robot's keyframes.
class LoopClosure {
 public:
  /// Uses `search`, or a RadiusCandidateSearch with `config.search` when null.
  explicit LoopClosure(const LoopClosureConfig& config = {},
                       std::unique_ptr<LoopCandidateSearch> search = nullptr);

  /// Indexes the next keyframe; call once per keyframe, in order.
  void add(const core::Keyframe& keyframe) { search_->add(keyframe); }

  /// Searches loops for the newest keyframe, `keyframes.back()`, and returns the
  /// first verified candidate. `T_world_keyframes[i]` estimates keyframe i. Keyframes
  /// within `skip_after_loop` of the last accepted loop are not searched.
  std::optional<IntraLoop> detect(std::span<const core::Keyframe> keyframes,
                                  std::span<const Eigen::Isometry3d> T_world_keyframes);

  /// Verifies `candidate` for `query`: ICP of the query's cloud against the submap of
  /// the candidate's neighbours (among the first `searchable` keyframes), from the
  /// relative pose of the estimates.
  [[nodiscard]] LoopVerification verify(std::span<const core::Keyframe> keyframes,
                                        std::span<const Eigen::Isometry3d> T_world_keyframes,
                                        core::KeyframeId candidate, core::KeyframeId query,
                                        std::size_t searchable) const;

  /// How many keyframes may be candidates for `query`: those older than the
  /// exclusion window (by count and by time).
  [[nodiscard]] std::size_t searchable(std::span<const core::Keyframe> keyframes,
                                       const core::Keyframe& query) const;

  /// What it did so far.
  [[nodiscard]] const LoopClosureStats& stats() const { return stats_; }

 private:
  [[nodiscard]] VoxelHashMap submap(std::span<const core::Keyframe> keyframes,
                                    std::span<const Eigen::Isometry3d> T_world_keyframes,
                                    std::size_t candidate, std::size_t searchable) const;
  [[nodiscard]] RegistrationResult registerCoarseToFine(
      std::span<const Eigen::Vector3d> points, const VoxelHashMap& map,
      const Eigen::Isometry3d& T_candidate_query_guess) const;
  [[nodiscard]] std::string judge(const RegistrationResult& result, double inlier_share) const;
  [[nodiscard]] core::Matrix6d loopInformation(const RegistrationResult& result) const;

  LoopClosureConfig config_;
  std::unique_ptr<LoopCandidateSearch> search_;
  LoopClosureStats stats_;
  std::optional<std::size_t> last_loop_query_;  ///< index of the last keyframe that closed a loop
};

}  // namespace dcl::odometry
