#include <Eigen/Eigenvalues>
#include <string>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/error.hpp>
#include <dcl/io/g2o.hpp>

namespace dcl::backend {
namespace {

std::string keyName(const core::PoseKey& key) {
  return core::robotName(key.robot) + std::to_string(key.keyframe.value());
}

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
    throw core::Error("pose graph: node " + keyName(key) +
                      " is not robot 0's; write it with symbol vertex ids");
  }
  return key.keyframe.value();
}

}  // namespace

std::string_view toString(FactorKind kind) {
  switch (kind) {
    case FactorKind::odometry:
      return "odometry";
    case FactorKind::intra_loop:
      return "intra_loop";
    case FactorKind::inter_loop:
      return "inter_loop";
  }
  return "unknown";
}

void PoseGraph::addNode(const core::PoseKey& key, const Eigen::Isometry3d& T_world_node) {
  nodes_[key] = T_world_node;
}

void PoseGraph::addFactor(const Factor& factor) {
  factors_.push_back(factor);
}

const Eigen::Isometry3d& PoseGraph::estimate(const core::PoseKey& key) const {
  const auto it = nodes_.find(key);
  if (it == nodes_.end()) throw core::Error("pose graph: no node " + keyName(key));
  return it->second;
}

void PoseGraph::setEstimate(const core::PoseKey& key, const Eigen::Isometry3d& T_world_node) {
  const auto it = nodes_.find(key);
  if (it == nodes_.end()) throw core::Error("pose graph: no node " + keyName(key));
  it->second = T_world_node;
}

bool PoseGraph::connects(const Factor& factor) const {
  return hasNode(factor.from) && hasNode(factor.to);
}

core::Vector6d factorResidual(const Factor& factor, const Eigen::Isometry3d& T_world_from,
                              const Eigen::Isometry3d& T_world_to) {
  return core::logSE3(factor.T_from_to.inverse() * T_world_from.inverse() * T_world_to);
}

double graphCost(const PoseGraph& graph) {
  double cost = 0.0;
  for (const Factor& f : graph.factors()) {
    if (!graph.connects(f)) continue;
    const core::Vector6d r = factorResidual(f, graph.estimate(f.from), graph.estimate(f.to));
    cost += r.dot(f.information * r);
  }
  return cost;
}

core::Matrix6d informationFromCovariance(const core::Matrix6d& covariance, double min_variance) {
  const Eigen::SelfAdjointEigenSolver<core::Matrix6d> eigen(0.5 *
                                                            (covariance + covariance.transpose()));
  const core::Vector6d inverse = eigen.eigenvalues().cwiseMax(min_variance).cwiseInverse();
  return eigen.eigenvectors() * inverse.asDiagonal() * eigen.eigenvectors().transpose();
}

core::PoseKey keyOfVertex(std::uint64_t id) {
  if (core::PoseKey::isSymbol(id)) return core::PoseKey::unpack(id);
  return {core::RobotId(0), core::KeyframeId(id)};
}

PoseGraph fromG2o(const io::G2oGraph& g2o) {
  PoseGraph graph;
  for (const auto& [id, pose] : g2o.vertices) graph.addNode(keyOfVertex(id), pose);
  for (const io::G2oEdge& e : g2o.edges) {
    const core::PoseKey from = keyOfVertex(e.from);
    const core::PoseKey to = keyOfVertex(e.to);
    graph.addFactor({from, to, e.T_from_to, e.information, kindOf(from, to)});
  }
  for (const std::uint64_t id : g2o.fixed) graph.fix(keyOfVertex(id));
  return graph;
}

io::G2oGraph toG2o(const PoseGraph& graph, VertexIds ids) {
  if (ids == VertexIds::automatic) {
    ids = singleRobotZero(graph) ? VertexIds::plain : VertexIds::symbols;
  }
  io::G2oGraph g2o;
  for (const auto& [key, pose] : graph.nodes()) g2o.vertices[vertexId(key, ids)] = pose;
  for (const Factor& f : graph.factors()) {
    g2o.edges.push_back({vertexId(f.from, ids), vertexId(f.to, ids), f.T_from_to, f.information});
  }
  for (const core::PoseKey& key : graph.fixedNodes()) g2o.fixed.insert(vertexId(key, ids));
  return g2o;
}

}  // namespace dcl::backend
