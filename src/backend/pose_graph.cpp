#include <Eigen/Eigenvalues>
#include <string>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/error.hpp>

namespace dcl::backend {

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

LoopId loopId(const Factor& loop) {
  if (loop.to.robot < loop.from.robot) return {loop.to, loop.from};
  return {loop.from, loop.to};
}

void PoseGraph::addNode(const core::PoseKey& key, const Eigen::Isometry3d& T_world_node) {
  nodes_[key] = T_world_node;
}

void PoseGraph::addFactor(const Factor& factor) {
  factors_.push_back(factor);
}

const Eigen::Isometry3d& PoseGraph::estimate(const core::PoseKey& key) const {
  const auto it = nodes_.find(key);
  if (it == nodes_.end()) throw core::Error("pose graph: no node " + core::keyName(key));
  return it->second;
}

void PoseGraph::setEstimate(const core::PoseKey& key, const Eigen::Isometry3d& T_world_node) {
  const auto it = nodes_.find(key);
  if (it == nodes_.end()) throw core::Error("pose graph: no node " + core::keyName(key));
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

}  // namespace dcl::backend
