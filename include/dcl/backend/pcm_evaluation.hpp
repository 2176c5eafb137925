#pragma once

/// Multi-robot graphs as the robust distributed-mapping benchmarks ship them,
/// and the precision and recall of PCM's verdict against an outlier-free
/// reference of the same graph.
///
/// A split graph is a folder of per-robot g2o files `0.g2o`, `1.g2o`, ... with
/// GTSAM-symbol vertex ids; each inter-robot loop is usually in both of its
/// robots' files. A reference is either such a folder or one g2o file; a file
/// with plain integer ids (a centralized "full graph") numbers robot a's
/// keyframes first, then robot b's, and so on (mixRobust's split graphs), or
/// uses keyframe indices no two robots share (distributed-mapper's). The
/// numbering is chosen, and checked, by the graph's odometry (same keys, same
/// measurements) before any loop is matched.

#include <cstddef>
#include <set>
#include <string>

#include <dcl/backend/pcm.hpp>
#include <dcl/backend/pose_graph.hpp>

namespace dcl::backend {

/// Reads a multi-robot pose graph: one g2o file, or a folder whose files named
/// `<number>.g2o` are the robots' graphs (other files are ignored), merged: an
/// inter-robot loop in several files counts once (the first, files in numeric
/// order). Every edge must join vertices the file (a folder: one of its robot
/// graphs) defines. In a folder the robot graphs are regular files numbered
/// from 0 without a gap, each holds the vertices of one robot, and no vertex
/// or robot is in two of them. Throws core::FileError naming the file and line
/// (the folder, for its numbering) otherwise, or for anything io::readG2o
/// refuses. With `skip_unknown_lines`, lines with an unknown tag (a damaged
/// line) are skipped with a warning naming them instead.
PoseGraph readMultiRobotGraph(const std::string& path, bool skip_unknown_lines = false);

/// The inter-robot loops of the outlier-free reference at `path` (a file or a
/// folder, as readMultiRobotGraph reads), named as `graph` names its nodes.
/// Throws core::FileError when the reference does not match the graph: under
/// no numbering are 90 % of the graph's odometry factors edges of the
/// reference between the same keys with the same measurement.
std::set<LoopId> readReferenceLoops(const std::string& path, const PoseGraph& graph);

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
