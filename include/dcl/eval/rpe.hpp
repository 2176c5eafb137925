#pragma once

/// Relative pose error as evo defines it, and the KITTI odometry metric as the KITTI devkit
/// (evaluate_odometry.cpp) computes it.

#include <cstddef>
#include <optional>
#include <string_view>
#include <utility>
#include <vector>

#include <dcl/eval/alignment.hpp>
#include <dcl/eval/association.hpp>
#include <dcl/eval/statistics.hpp>

namespace dcl::eval {

/// A pair of pose indices (i, j), i < j.
using IndexPair = std::pair<std::size_t, std::size_t>;

/// The unit of the RPE's delta.
enum class DeltaUnit {
  frames,  ///< index distance (evo's filter_pairs_by_index)
  meters,  ///< travelled path (evo's filter_pairs_by_path)
};

/// "frames" or "meters".
std::string_view toString(DeltaUnit unit);

/// Parses "frames" or "meters" ("m" too); throws core::Error otherwise.
DeltaUnit parseDeltaUnit(std::string_view name);

/// Settings of the KITTI odometry metric; the defaults are the devkit's.
struct KittiOptions {
  std::vector<double> lengths{100, 200, 300, 400,
                              500, 600, 700, 800};  ///< metres; default 100..800
  std::size_t step = 10;  ///< frames between segment starts; default 10 (one second at 10 Hz)
};

/// The KITTI metric's figures for one segment length.
struct KittiLength {
  double length_m = 0.0;               ///< nominal segment length
  std::size_t segments = 0;            ///< segments of this length
  double translation_percent = 0.0;    ///< mean translation error / length, percent
  double rotation_deg_per_100m = 0.0;  ///< mean rotation error / length, degrees per 100 m
};

/// The KITTI odometry metric: mean over all segments of (error / nominal length).
struct KittiResult {
  double translation_percent = 0.0;     ///< mean t_err / length, percent
  double rotation_deg_per_m = 0.0;      ///< mean r_err / length, degrees per metre
  double rotation_deg_per_100m = 0.0;   ///< the same, degrees per 100 m
  std::size_t segments = 0;             ///< number of segments averaged
  std::vector<KittiLength> per_length;  ///< breakdown by segment length (lengths with segments)
};

/// Settings of the RPE; the defaults are evo_rpe's.
struct RpeOptions {
  double delta = 1.0;                        ///< default 1: pair distance in `delta_unit`
  DeltaUnit delta_unit = DeltaUnit::frames;  ///< default frames
  bool all_pairs = false;                    ///< default false: consecutive pairs only
  double rel_delta_tol = 0.1;                ///< default 0.1: path tolerance (meters, all pairs)
  bool pairs_from_reference = false;         ///< default false: pairs chosen on the estimate
  Alignment alignment = Alignment::none;     ///< default none (matters for sim3 only)
  bool kitti = true;                         ///< default true: also compute the KITTI metric
  KittiOptions kitti_options{};              ///< default: the devkit's lengths and step
  AssociationOptions association{};          ///< default: nearest stamp within 0.01 s
};

/// The RPE of one estimate against its ground truth.
struct RpeResult {
  Statistics translation_m;                ///< |t(E_ij)| per pair, metres
  Statistics rotation_deg;                 ///< angle(E_ij) per pair, degrees
  Alignment alignment = Alignment::none;   ///< alignment applied before measuring
  Sim3 S_gt_est;                           ///< the transformation applied to the estimate
  std::vector<IndexPair> pairs;            ///< the (i, j) pairs, indices into the association
  std::vector<double> translation_errors;  ///< per pair, metres
  std::vector<double> rotation_errors;     ///< per pair, degrees
  /// The KITTI metric on the same (aligned) pairs; none when no segment fits (a path shorter
  /// than the shortest length) or when not asked for.
  std::optional<KittiResult> kitti;
};

/// evo's filter_pairs_by_index: (i, i + delta) for every i when `all_pairs`, else the
/// consecutive pairs of 0, delta, 2 delta, ... Throws core::Error for delta 0.
std::vector<IndexPair> pairsByIndex(std::size_t size, std::size_t delta, bool all_pairs);

/// evo's filter_pairs_by_path. Consecutive: the poses where the path travelled since the last
/// one reaches `delta` (the first is the first such pose, not pose 0), paired in turn. All
/// pairs: for each i, the j > i whose path length from i is nearest `delta`, kept within `tol`.
std::vector<IndexPair> pairsByPath(const core::Trajectory& trajectory, double delta, double tol,
                                   bool all_pairs);

/// The relative pose error of one pair (TUM RGB-D benchmark notation):
/// E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j), Q ground truth, P estimate.
Eigen::Isometry3d relativeError(const Eigen::Isometry3d& Q_i, const Eigen::Isometry3d& Q_j,
                                const Eigen::Isometry3d& P_i, const Eigen::Isometry3d& P_j);

/// The RPE of associated pairs. Throws core::Error when no pair fits the delta.
RpeResult computeRpe(const Association& pairs, const RpeOptions& options = {});

/// The RPE of `estimate` against `ground_truth`: associate, align, measure.
RpeResult computeRpe(const core::Trajectory& estimate, const core::Trajectory& ground_truth,
                     const RpeOptions& options = {});

/// The KITTI odometry metric of associated pairs (devkit's calcSequenceErrors in double
/// precision): segments start every `step` frames; a segment of length L ends at the first
/// frame whose ground-truth path from the start exceeds L; its errors are those of
/// (P_i^-1 P_j)^-1 (Q_i^-1 Q_j), divided by L. None when no segment fits.
std::optional<KittiResult> computeKittiMetric(const Association& pairs,
                                              const KittiOptions& options = {});

}  // namespace dcl::eval
