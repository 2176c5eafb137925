#pragma once

/// A g2o / TORO graph (g2o.hpp) as the back-end's backend::PoseGraph and back:
/// the reader of a graph file and the writer of a run's graph.
///
/// Vertex ids that are GTSAM symbols become their robot and keyframe, plain
/// ids robot 0 and keyframe id. Factor kinds: ends of different robots give
/// inter_loop, consecutive keyframes of one robot odometry, others intra_loop.

#include <cstdint>
#include <string>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/ids.hpp>
#include <dcl/io/g2o.hpp>

namespace dcl::io {

/// How g2o vertex ids map to pose keys when converting.
enum class VertexIds {
  automatic,  ///< to g2o: plain keyframe indices when every node is robot 0, else symbols
  plain,      ///< to g2o: the keyframe index (throws core::Error for a graph of several robots)
  symbols,    ///< to g2o: GTSAM symbols (core::PoseKey::pack)
};

/// The key of a g2o vertex id: a GTSAM symbol names its robot and keyframe, a
/// plain integer is robot 0's keyframe.
core::PoseKey keyOfVertex(std::uint64_t id);

/// A pose graph from a g2o / TORO graph read by readG2o. `FIX` lines become
/// fixed nodes; TORO `EQUIV` lines are ignored.
backend::PoseGraph toPoseGraph(const G2oGraph& g2o);

/// The graph as a G2oGraph (3D), for writeG2o; vertex ids as `ids` says.
G2oGraph toG2o(const backend::PoseGraph& graph, VertexIds ids = VertexIds::automatic);

/// Reads the g2o or TORO graph at `path` (readG2o, whose errors it raises) as a pose graph.
backend::PoseGraph readPoseGraph(const std::string& path, const G2oReadOptions& options = {});

/// Writes `graph` as g2o text (toG2o, writeG2o), atomically.
void writePoseGraph(const std::string& path, const backend::PoseGraph& graph,
                    VertexIds ids = VertexIds::automatic);

}  // namespace dcl::io
