#pragma once

/// Candidate loops graded by the ground truth, stage by stage (`dcl-slam
/// bench loops`): which candidates were real revisits, which verified loops
/// measure the true relative pose, which of those outlier rejection kept,
/// and the precision and recall of what it kept.

#include <Eigen/Geometry>
#include <cstddef>
#include <vector>

namespace dcl::eval {

/// How far a measured relative pose is from the ground truth's.
struct LoopError {
  double translation_m = 0.0;  ///< |t| of T_true^-1 T_measured
  double rotation_deg = 0.0;   ///< the rotation angle of T_true^-1 T_measured
};

/// The error of the measurement `T_a_b` (keyframe b in the frame of keyframe
/// a) against the ground truth poses of a and b.
LoopError loopError(const Eigen::Isometry3d& T_a_b, const Eigen::Isometry3d& T_world_a,
                    const Eigen::Isometry3d& T_world_b);

/// The largest error of a correct loop.
struct LoopTolerance {
  double max_error_m = 1.0;    ///< m, translation; default 1
  double max_error_deg = 2.0;  ///< deg, rotation; default 2
};

/// True when `error` is within `tolerance` on both counts.
bool isCorrect(const LoopError& error, const LoopTolerance& tolerance);

/// One candidate loop, and what became of it.
struct CandidateLoop {
  double ground_truth_m = 0.0;  ///< true distance between its two keyframes
  bool verified = false;        ///< geometric verification accepted it
  bool correct = false;         ///< verified, and within the tolerance (isCorrect)
  bool kept = false;            ///< outlier rejection kept it, and nothing withdrew it after
  bool withdrawn = false;       ///< outlier rejection kept it, a later check withdrew it
};

/// Candidate loops counted stage by stage. Correct, kept and withdrawn
/// loops are counted among the verified ones only.
struct LoopCounts {
  std::size_t candidates = 0;
  std::size_t candidates_true = 0;  ///< real revisits: true distance below the true-loop distance
  std::size_t verified = 0;
  std::size_t verified_correct = 0;
  std::size_t verified_wrong = 0;
  std::size_t kept = 0;
  std::size_t kept_correct = 0;
  std::size_t kept_wrong = 0;
  std::size_t withdrawn = 0;
  std::size_t withdrawn_correct = 0;
  double precision = 1.0;  ///< kept_correct / kept (1 when none is kept)
  double recall = 0.0;     ///< kept_correct / verified_correct (0 when none is correct)
};

/// The counts of `candidates`; a candidate is a real revisit when its
/// keyframes lie less than `true_loop_distance` (m) apart.
LoopCounts countLoops(const std::vector<CandidateLoop>& candidates, double true_loop_distance);

}  // namespace dcl::eval
