#pragma once

/// Multi-robot graphs as the robust distributed-mapping benchmarks ship them,
/// and their outlier-free references: the inputs of PCM's evaluation
/// (backend/pcm_evaluation.hpp scores the verdict against the reference).
///
/// A split graph is a folder of per-robot g2o files `0.g2o`, `1.g2o`, ... with
/// GTSAM-symbol vertex ids; each inter-robot loop is usually in both of its
/// robots' files. A reference is either such a folder or one g2o file; a file
/// with plain integer ids (a centralized "full graph") numbers robot a's
/// keyframes first, then robot b's, and so on (mixRobust's split graphs), or
/// uses keyframe indices no two robots share (distributed-mapper's). The
/// numbering is chosen, and checked, by the graph's odometry (same keys, same
/// measurements) before any loop is matched.

#include <set>
#include <string>

#include <dcl/backend/pose_graph.hpp>

namespace dcl::io {

/// Reads a multi-robot pose graph: one g2o file, or a folder whose files named
/// `<number>.g2o` are the robots' graphs (other files are ignored), merged: an
/// inter-robot loop in several files counts once (the first, files in numeric
/// order). Every edge must join vertices the file (a folder: one of its robot
/// graphs) defines. In a folder the robot graphs are regular files numbered
/// from 0 without a gap, each holds the vertices of one robot, and no vertex
/// or robot is in two of them. Throws core::FileError naming the file and line
/// (the folder, for its numbering) otherwise, or for anything readG2o
/// refuses. With `skip_unknown_lines`, lines with an unknown tag (a damaged
/// line) are skipped with a warning naming them instead.
backend::PoseGraph readMultiRobotGraph(const std::string& path, bool skip_unknown_lines = false);

/// The inter-robot loops of the outlier-free reference at `path` (a file or a
/// folder, as readMultiRobotGraph reads), named as `graph` names its nodes.
/// Throws core::FileError when the reference does not match the graph: under
/// no numbering are 90 % of the graph's odometry factors edges of the
/// reference between the same keys with the same measurement.
std::set<backend::LoopId> readReferenceLoops(const std::string& path,
                                             const backend::PoseGraph& graph);

}  // namespace dcl::io
