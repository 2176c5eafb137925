#pragma once

/// The precision and recall of PCM's verdict against the inter-robot loops of
/// an outlier-free reference of the same graph (the graph and the reference's
/// loops are read by io/multi_robot_graph.hpp).

#include <cstddef>
#include <set>

#include <dcl/backend/pcm.hpp>

namespace dcl::backend {

/// PCM's kept loops scored against the reference's inlier loops.
struct LoopScore {
  std::size_t candidates = 0;  ///< loops PCM was given
  std::size_t inliers = 0;     ///< candidates that are reference loops
  std::size_t kept = 0;        ///< loops PCM accepted
  std::size_t true_kept = 0;   ///< accepted reference loops
  double precision = 1.0;      ///< true_kept / kept (1 when none is kept)
  double recall = 1.0;         ///< true_kept / inliers (1 when there is no inlier)
};

/// The precision and recall of `result`'s accepted loops as the inlier set.
LoopScore scoreLoops(const PcmResult& result, const std::set<LoopId>& reference);

}  // namespace dcl::backend
