#include <string>

#include <dcl/core/error.hpp>
#include <dcl/io/pose_graph_g2o.hpp>

namespace dcl::io {
namespace {

using backend::Factor;
using backend::FactorKind;
using backend::PoseGraph;

FactorKind kindOf(const core::PoseKey& from, const core::PoseKey& to) {
  if (from.robot != to.robot) return FactorKind::inter_loop;
  const auto a = from.keyframe.value();
  const auto b = to.keyframe.value();
  return (a + 1 == b || b + 1 == a) ? FactorKind::odometry : FactorKind::intra_loop;
}

bool singleRobotZero(const PoseGraph& graph) {
  const auto robot0 = [](const core::PoseKey& key) { return key.robot == core::RobotId(0); };
  for (const auto& [key, pose] : graph.nodes()) {
    if (!robot0(key)) return false;
  }
  for (const Factor& f : graph.factors()) {
    if (!robot0(f.from) || !robot0(f.to)) return false;
  }
  return true;
}

std::uint64_t vertexId(const core::PoseKey& key, VertexIds ids) {
  if (ids == VertexIds::symbols) return key.pack();
  if (key.robot != core::RobotId(0)) {
    throw core::Error("pose graph: node " + core::keyName(key) +
                      " is not robot 0's; write it with symbol vertex ids");
  }
  return key.keyframe.value();
}

}  // namespace

core::PoseKey keyOfVertex(std::uint64_t id) {
  if (core::PoseKey::isSymbol(id)) return core::PoseKey::unpack(id);
  return {core::RobotId(0), core::KeyframeId(id)};
}

PoseGraph toPoseGraph(const G2oGraph& g2o) {
  PoseGraph graph;
  for (const auto& [id, pose] : g2o.vertices) graph.addNode(keyOfVertex(id), pose);
  for (const G2oEdge& e : g2o.edges) {
    const core::PoseKey from = keyOfVertex(e.from);
    const core::PoseKey to = keyOfVertex(e.to);
    graph.addFactor({from, to, e.T_from_to, e.information, kindOf(from, to)});
  }
  for (const std::uint64_t id : g2o.fixed) graph.fix(keyOfVertex(id));
  return graph;
}

G2oGraph toG2o(const PoseGraph& graph, VertexIds ids) {
  if (ids == VertexIds::automatic) {
    ids = singleRobotZero(graph) ? VertexIds::plain : VertexIds::symbols;
  }
  G2oGraph g2o;
  for (const auto& [key, pose] : graph.nodes()) g2o.vertices[vertexId(key, ids)] = pose;
  for (const Factor& f : graph.factors()) {
    g2o.edges.push_back({vertexId(f.from, ids), vertexId(f.to, ids), f.T_from_to, f.information});
  }
  for (const core::PoseKey& key : graph.fixedNodes()) g2o.fixed.insert(vertexId(key, ids));
  return g2o;
}

PoseGraph readPoseGraph(const std::string& path, const G2oReadOptions& options) {
  return toPoseGraph(readG2o(path, options));
}

void writePoseGraph(const std::string& path, const PoseGraph& graph, VertexIds ids) {
  writeG2o(path, toG2o(graph, ids));
}

}  // namespace dcl::io
