#include <cmath>

#include <dcl/core/se3.hpp>
#include <dcl/eval/loop_scoring.hpp>

namespace dcl::eval {
namespace {

double ratio(std::size_t a, std::size_t b) {
  return b == 0 ? 0.0 : static_cast<double>(a) / static_cast<double>(b);
}

}  // namespace

LoopError loopError(const Eigen::Isometry3d& T_a_b, const Eigen::Isometry3d& T_world_a,
                    const Eigen::Isometry3d& T_world_b) {
  const Eigen::Isometry3d truth = T_world_a.inverse() * T_world_b;
  const Eigen::Isometry3d error = truth.inverse() * T_a_b;
  return {error.translation().norm(), core::rad2deg(core::rotationAngle(error.rotation()))};
}

bool isCorrect(const LoopError& error, const LoopTolerance& tolerance) {
  return error.translation_m <= tolerance.max_error_m &&
         error.rotation_deg <= tolerance.max_error_deg;
}

LoopCounts countLoops(const std::vector<CandidateLoop>& candidates, double true_loop_distance) {
  LoopCounts n;
  n.candidates = candidates.size();
  for (const CandidateLoop& c : candidates) {
    n.candidates_true += c.ground_truth_m < true_loop_distance ? 1 : 0;
    if (!c.verified) continue;
    ++n.verified;
    n.verified_correct += c.correct ? 1 : 0;
    n.kept += c.kept ? 1 : 0;
    n.kept_correct += c.kept && c.correct ? 1 : 0;
    n.withdrawn += c.withdrawn ? 1 : 0;
    n.withdrawn_correct += c.withdrawn && c.correct ? 1 : 0;
  }
  n.verified_wrong = n.verified - n.verified_correct;
  n.kept_wrong = n.kept - n.kept_correct;
  n.precision = n.kept == 0 ? 1.0 : ratio(n.kept_correct, n.kept);
  n.recall = ratio(n.kept_correct, n.verified_correct);
  return n;
}

}  // namespace dcl::eval
