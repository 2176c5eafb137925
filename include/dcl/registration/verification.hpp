#pragma once

/// Loop verification (paper §III-B, "Verification"): the verifying robot
/// aligns the querying robot's keyframe cloud with its own submap around the
/// matched keyframe and either returns a relative pose with its covariance or
/// says why it refused.
///
/// The alignment starts from the yaw that place recognition found (LiDAR-Iris
/// phase correlation) and no translation, and refines it by GICP, coarse gate
/// first, then fine. When that does not settle on a good alignment (the yaw
/// was off, the robots were metres apart), FPFH features and RANSAC find a
/// global alignment without any guess, which GICP refines in turn. A result
/// is accepted when the share of query points that found a partner, the RMS
/// distance of those pairs and the conditioning of the alignment are all within
/// bounds; each refusal names its reason, counted in VerificationStats.

#include <Eigen/Geometry>
#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <string_view>

#include <dcl/core/keyframe.hpp>
#include <dcl/core/point_cloud.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/registration/fpfh.hpp>
#include <dcl/registration/ransac.hpp>

namespace dcl::registration {

/// How loops are verified. Defaults from the paper (inlier share 0.3, submap
/// of +/-10 keyframes) and, where it is silent, for a road vehicle with an
/// HDL-64, tuned on KITTI 00. A near-field scene (most returns within 10 m)
/// wants a finer grid: voxel_size 0.2, max_correspondence_distance 0.5,
/// inlier_distance 0.1 verify the outdoor test pair.
struct VerificationConfig {
  /// m, grid of the query and the submap for GICP; keep CloudCodecConfig::voxel_size
  /// equal. 0.6 m: an HDL-64 keyframe's compact cloud fits in 25 kB, and KITTI
  /// loops align within 1-2 cm (0.5 m: 28 kB, no more accurate).
  double voxel_size = 0.6;
  int shape_neighbors = 10;                     ///< nearest points of a GICP covariance and normal
  double coarse_correspondence_distance = 2.5;  ///< m, GICP gate of the first stage
  double max_correspondence_distance = 1.0;     ///< m, GICP gate of the fine stage
  int max_iterations = 30;                      ///< Gauss-Newton iterations a stage
  /// m, a query point is an inlier when a submap point is this close after alignment
  double inlier_distance = 0.25;
  double min_inlier_share = 0.3;  ///< share of query points that are inliers, at least (paper)
  double max_fitness = 0.45;      ///< m, RMS distance of the fine stage's pairs, at most
  /// Weakest/strongest scaled eigenvalue of the point-to-plane information, at
  /// least: below, some direction of the alignment is left to chance.
  double min_degeneracy = 0.003;
  std::size_t min_points = 100;     ///< fewer filtered points in query or submap: refused
  bool ransac_fallback = true;      ///< run FPFH + RANSAC when the yaw-initialised alignment fails
  double feature_voxel_size = 1.0;  ///< m, grid of the clouds the features are computed on
  FpfhConfig fpfh;                  ///< the features of the fallback
  RansacConfig ransac;              ///< the global registration of the fallback
  int submap_keyframes = 10;        ///< keyframes either side of the matched one in its submap
  /// An accepted alignment is tried again with the query turned half a turn
  /// about its own vertical axis; when that aligns too, with at least this
  /// share of the first one's inliers, the place looks the same both ways
  /// (a symmetric corridor, a straight street of repeated facades) and the
  /// loop is refused as ambiguous: which way round it is, is chance. 0: not
  /// checked. Robots driving one street in opposite directions meet exactly
  /// there, and LiDAR-Iris's yaw finds both driving directions alike.
  double symmetric_share = 0.9;

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("voxel_size", voxel_size, "m, grid of the query and the submap for GICP")
        .within(core::kMinVoxelEdge, core::kMaxVoxelEdge);
    // A covariance and a normal need three points; the search returns kMaxNeighbors at most.
    v.field("shape_neighbors", shape_neighbors, "nearest points of a covariance and normal")
        .within(3, static_cast<int>(PointTree::kMaxNeighbors));
    v.field("coarse_correspondence_distance", coarse_correspondence_distance,
            "m, GICP gate of the first stage")
        .positive();
    v.field("max_correspondence_distance", max_correspondence_distance,
            "m, GICP gate of the fine stage")
        .positive();
    v.field("max_iterations", max_iterations, "Gauss-Newton iterations a stage").positive();
    v.field("inlier_distance", inlier_distance,
            "m, a query point this close to the submap is an inlier")
        .positive();
    v.field("min_inlier_share", min_inlier_share,
            "share of query points that are inliers, at least")
        .within(0.0, 1.0);
    v.field("max_fitness", max_fitness, "m, RMS distance of the pairs, at most").positive();
    v.field("min_degeneracy", min_degeneracy,
            "weakest/strongest scaled eigenvalue of the alignment, at least")
        .within(0.0, 1.0, core::Interval::open_high);
    v.field("min_points", min_points, "fewest filtered points in query and submap");
    v.field("ransac_fallback", ransac_fallback,
            "FPFH + RANSAC when the yaw-initialised alignment fails");
    v.field("feature_voxel_size", feature_voxel_size, "m, grid of the feature clouds")
        .within(core::kMinVoxelEdge, core::kMaxVoxelEdge);
    v.section("fpfh", fpfh, "FPFH features of the fallback");
    v.section("ransac", ransac, "RANSAC global registration of the fallback");
    v.field("submap_keyframes", submap_keyframes, "keyframes either side in the submap")
        .nonNegative();
    v.field("symmetric_share", symmetric_share,
            "refuse a loop that also aligns turned half a turn, with this share of its inliers "
            "(0: not checked)")
        .within(0.0, 1.0);
  }
};

/// Why a candidate was refused.
enum class RejectReason : std::uint8_t {
  none,              ///< accepted
  too_few_points,    ///< the query or the submap has fewer than min_points after filtering
  not_converged,     ///< no alignment settled (GICP and, if tried, RANSAC)
  low_inlier_share,  ///< too few query points lie on the submap after alignment
  high_fitness,      ///< the pairs are too far apart on average
  degenerate,        ///< the scene leaves a direction of the alignment unconstrained
  symmetric,         ///< the query aligns as well turned half a turn: the way round is chance
};

/// Number of RejectReason values (for per-reason counters).
inline constexpr std::size_t kRejectReasonCount = 7;

/// "none", "too_few_points", "not_converged", "low_inlier_share", "high_fitness", "degenerate",
/// "symmetric".
std::string_view toString(RejectReason reason);

/// The outcome of one verification.
struct VerificationResult {
  bool accepted = false;
  RejectReason reason = RejectReason::not_converged;  ///< none when accepted
  /// Maps points from the query keyframe's frame into the candidate's (the
  /// matched keyframe of the verifying robot): the loop factor's T_from_to with
  /// from = candidate, to = query. Meaningful only when accepted.
  Eigen::Isometry3d T_candidate_query = Eigen::Isometry3d::Identity();
  /// Covariance of T_candidate_query over [rho; phi], perturbation on the right
  /// (GicpResult::covariance of the final alignment).
  core::Matrix6d covariance = core::Matrix6d::Identity();
  double inlier_share = 0.0;      ///< filtered query points within inlier_distance / all of them
  double fitness = 0.0;           ///< m, RMS distance of the pairs
  double degeneracy = 0.0;        ///< GicpResult::degeneracy of the final alignment
  bool used_ransac = false;       ///< the final alignment started from the RANSAC estimate
  int iterations = 0;             ///< GICP iterations over all stages and attempts
  std::size_t query_points = 0;   ///< query points after filtering
  std::size_t submap_points = 0;  ///< submap points after filtering
};

/// Counts of verification outcomes, for diagnostics (metrics.json).
struct VerificationStats {
  std::size_t attempts = 0;  ///< verifications run
  std::size_t accepted = 0;  ///< of which accepted
  std::size_t ransac = 0;    ///< of which the final alignment came from the RANSAC fallback
  std::array<std::size_t, kRejectReasonCount> rejected{};  ///< refusals by reason

  /// Counts `result`.
  void add(const VerificationResult& result);
  /// Refusals for `reason` (attempts - all refusals for none).
  [[nodiscard]] std::size_t count(RejectReason reason) const;
};

/// Verifies a loop candidate. `query_cloud` is the querying robot's keyframe
/// cloud in its own frame, as received (full resolution or the compact cloud);
/// `yaw_guess` (rad) the yaw of T_candidate_query from place recognition (the
/// negative of place::Match::yaw_rad, which is that of T_query_candidate);
/// `submap_cloud` the verifying robot's submap, already in the matched
/// keyframe's frame (buildSubmap). Throws core::Error only for an invalid
/// configuration; bad clouds are refused with a reason.
VerificationResult verifyLoop(const core::PointCloud& query_cloud, double yaw_guess,
                              const core::PointCloud& submap_cloud,
                              const VerificationConfig& config = {});

/// The points of the keyframes within `radius` of keyframes[center] in the
/// span (and of the same robot), in the frame of keyframes[center], placed by
/// their odometry poses; voxel-filtered at `voxel_size` when it is positive,
/// so that twenty keyframes do not hold millions of points. Only the points are
/// kept. Throws core::Error when `center` is outside the span or `radius` is negative.
core::PointCloud buildSubmap(std::span<const core::Keyframe> keyframes, std::size_t center,
                             int radius, double voxel_size = 0.0);

/// Throws core::Error naming the first field that breaks its rule (visit()).
void validate(const VerificationConfig& config);

}  // namespace dcl::registration
