#pragma once

/// Absolute trajectory error: evo's APE, translation part (m) and rotation angle (deg).

#include <cstddef>
#include <vector>

#include <dcl/eval/alignment.hpp>
#include <dcl/eval/association.hpp>
#include <dcl/eval/statistics.hpp>

namespace dcl::eval {

/// Settings of the ATE.
struct AteOptions {
  Alignment alignment = Alignment::se3;  ///< default se3 (evo_ape -a); evo's own default is none
  AssociationOptions association{};      ///< default: nearest stamp within 0.01 s
};

/// The ATE of one estimate against its ground truth.
struct AteResult {
  Statistics translation_m;                ///< |p_gt - p_est_aligned| per pair, metres
  Statistics rotation_deg;                 ///< angle of R_gt^T R_est_aligned per pair, degrees
  Alignment alignment = Alignment::none;   ///< the alignment applied
  Sim3 S_gt_est;                           ///< the transformation applied to the estimate
  std::size_t pairs = 0;                   ///< number of associated pose pairs
  std::vector<double> translation_errors;  ///< per pair, metres (for plots)
  std::vector<double> rotation_errors;     ///< per pair, degrees (for plots)
};

/// The ATE of associated pairs under a given transformation of the estimate (no fitting).
AteResult computeAte(const Association& pairs, const Sim3& S_gt_est, Alignment alignment);

/// The ATE of associated pairs, the estimate aligned by `alignment` on all pairs first.
AteResult computeAte(const Association& pairs, Alignment alignment);

/// The ATE of `estimate` against `ground_truth`: associate, align, measure.
AteResult computeAte(const core::Trajectory& estimate, const core::Trajectory& ground_truth,
                     const AteOptions& options = {});

/// Settings of the multi-robot ATE.
struct MultiRobotAteOptions {
  Alignment alignment = Alignment::se3;  ///< default se3: the swarm shares one rigid frame
  std::size_t reference_robot = 0;       ///< default 0: the robot whose pairs fix the alignment
};

/// The multi-robot ATE of the paper's protocol: one alignment for the whole swarm.
struct MultiRobotAteResult {
  Sim3 S_gt_est;                    ///< the alignment, fitted on the reference robot's pairs only
  std::size_t reference_robot = 0;  ///< index of the robot the alignment was fitted on
  std::vector<AteResult> robots;    ///< per robot, under the common alignment
  AteResult pooled;                 ///< all robots' pairs together, under the common alignment
};

/// The ATE of a swarm: every robot's estimate is in one shared map frame, so one alignment,
/// fitted on the reference robot's associated trajectory, is applied to every robot; errors are
/// reported per robot and pooled over all pairs. Throws core::Error for an empty swarm or a
/// reference robot out of range.
MultiRobotAteResult computeMultiRobotAte(const std::vector<Association>& robots,
                                         const MultiRobotAteOptions& options = {});

}  // namespace dcl::eval
