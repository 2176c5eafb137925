#include <dcl/backend/pcm_evaluation.hpp>

namespace dcl::backend {

LoopScore scoreLoops(const PcmResult& result, const std::set<LoopId>& reference) {
  LoopScore s;
  for (const PcmPairResult& pair : result.pairs) {
    const PcmDecision& d = pair.decision;
    for (const auto* list : {&d.accepted, &d.rejected, &d.unverified, &d.withdrawn}) {
      for (const Factor& f : *list) {
        ++s.candidates;
        const bool inlier = reference.contains(loopId(f));
        s.inliers += inlier ? 1 : 0;
        if (list != &d.accepted) continue;
        ++s.kept;
        s.true_kept += inlier ? 1 : 0;
      }
    }
  }
  if (s.kept > 0) s.precision = static_cast<double>(s.true_kept) / static_cast<double>(s.kept);
  if (s.inliers > 0) s.recall = static_cast<double>(s.true_kept) / static_cast<double>(s.inliers);
  return s;
}

}  // namespace dcl::backend
