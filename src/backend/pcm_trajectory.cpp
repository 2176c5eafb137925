#include <deque>
#include <string>

#include <fmt/format.h>

#include <dcl/backend/pcm_trajectory.hpp>
#include <dcl/core/error.hpp>

namespace dcl::backend {
namespace {

/// Smallest information eigenvalue used when inverting an information matrix.
constexpr double kMinInformation = 1e-12;

/// A Sigma A^T, symmetrised.
core::Matrix6d transportedSymmetric(const core::Matrix6d& A, const core::Matrix6d& sigma) {
  const core::Matrix6d m = A * sigma * A.transpose();
  return 0.5 * (m + m.transpose());
}

/// T^-1 and its covariance, Ad(T) Sigma Ad(T)^T.
RelativePose inverted(const RelativePose& p) {
  return {p.T_i_j.inverse(), transportedSymmetric(core::adjoint(p.T_i_j), p.covariance)};
}

}  // namespace

core::Matrix6d covarianceOf(const core::Matrix6d& information) {
  // Inverting a symmetric matrix with clamped eigenvalues is the same operation
  // in both directions.
  return informationFromCovariance(information, kMinInformation);
}

TrajectoryTree::TrajectoryTree(core::RobotId robot, core::KeyframeId origin, bool intra_loops)
    : robot_(robot), origin_(origin), intra_loops_(intra_loops) {
  nodes_.push_back({.keyframe = origin.value(), .parent_keyframe = origin.value()});
  node_of_.emplace(origin.value(), 0);
}

void TrajectoryTree::add(const Factor& factor) {
  const auto describe = [&] {
    return fmt::format("trajectory of robot {}: factor {} -> {}", core::robotName(robot_),
                       core::keyName(factor.from), core::keyName(factor.to));
  };
  if (factor.from.robot != robot_ || factor.to.robot != robot_) {
    throw core::Error(describe() + " is not between two of its keyframes");
  }
  const std::uint64_t from = factor.from.keyframe.value();
  const std::uint64_t to = factor.to.keyframe.value();
  if (from == to) throw core::Error(describe() + " joins a keyframe to itself");
  const bool odometry = factor.kind == FactorKind::odometry;
  if (odometry && from + 1 != to && to + 1 != from) {
    throw core::Error(describe() + " is odometry between keyframes that are not consecutive");
  }
  if (!odometry && !intra_loops_) return;
  auto& out = edges_[from];
  if (out.contains(to)) return;
  const RelativePose forward{factor.T_from_to, covarianceOf(factor.information)};
  const RelativePose backward = inverted(forward);
  out.emplace(to, Edge{forward.T_i_j, forward.covariance});
  auto& in = edges_[to];
  in.emplace(from, Edge{backward.T_i_j, backward.covariance});
  // The next keyframe's odometry from a keyframe of the tree: a new leaf, as a
  // rebuild would attach it (its only neighbour is its parent).
  const auto leaf = [&](std::uint64_t parent, std::uint64_t child, const Edge& edge) {
    const auto it = node_of_.find(parent);
    if (dirty_ || it == node_of_.end() || node_of_.contains(child) || edges_[child].size() != 1) {
      return false;
    }
    attach(child, it->second, edge);
    return true;
  };
  if (leaf(from, to, out.at(to)) || leaf(to, from, in.at(from))) return;
  dirty_ = true;
}

void TrajectoryTree::refresh() const {
  if (dirty_) rebuild();
}

void TrajectoryTree::rebuild() const {
  std::unordered_map<std::uint64_t, std::uint64_t> old_parent;
  for (const Node& n : nodes_) old_parent.emplace(n.keyframe, n.parent_keyframe);
  nodes_.resize(1);
  node_of_.clear();
  node_of_.emplace(origin_.value(), 0);
  for (std::size_t u = 0; u < nodes_.size(); ++u) {  // breadth first: nodes_ is the queue
    const auto it = edges_.find(nodes_[u].keyframe);
    if (it == edges_.end()) continue;
    for (const auto& [neighbour, edge] : it->second) {
      if (!node_of_.contains(neighbour)) attach(neighbour, static_cast<std::uint32_t>(u), edge);
    }
  }
  for (const auto& [keyframe, parent] : old_parent) {
    const auto it = node_of_.find(keyframe);
    if (it == node_of_.end() || nodes_[it->second].parent_keyframe != parent) {
      ++revision_;
      break;
    }
  }
  dirty_ = false;
}

void TrajectoryTree::attach(std::uint64_t keyframe, std::uint32_t parent, const Edge& edge) const {
  const Node& p = nodes_[parent];
  Node n{.keyframe = keyframe,
         .parent_keyframe = p.keyframe,
         .T_origin_k = p.T_origin_k * edge.T,
         .covariance =
             transportedSymmetric(core::adjoint(edge.T.inverse()), p.covariance) + edge.covariance,
         .depth = p.depth + 1};
  n.up[0] = parent;
  for (std::size_t l = 1; l < kLevels; ++l) n.up[l] = nodes_[n.up[l - 1]].up[l - 1];
  node_of_.emplace(keyframe, static_cast<std::uint32_t>(nodes_.size()));
  nodes_.push_back(n);
}

bool TrajectoryTree::reaches(core::KeyframeId k) const {
  refresh();
  return node_of_.contains(k.value());
}

std::size_t TrajectoryTree::size() const {
  refresh();
  return nodes_.size();
}

std::uint64_t TrajectoryTree::revision() const {
  refresh();
  return revision_;
}

std::uint32_t TrajectoryTree::nodeOf(core::KeyframeId k) const {
  const auto it = node_of_.find(k.value());
  if (it == node_of_.end()) {
    throw core::Error(fmt::format("trajectory of robot {} does not reach keyframe {}",
                                  core::robotName(robot_), k.value()));
  }
  return it->second;
}

std::uint32_t TrajectoryTree::lowestCommonAncestor(std::uint32_t u, std::uint32_t v) const {
  if (nodes_[u].depth < nodes_[v].depth) std::swap(u, v);
  for (std::uint32_t rise = nodes_[u].depth - nodes_[v].depth, l = 0; rise != 0; rise >>= 1, ++l) {
    if ((rise & 1U) != 0) u = nodes_[u].up[l];
  }
  if (u == v) return u;
  for (std::size_t l = kLevels; l-- > 0;) {
    if (nodes_[u].up[l] != nodes_[v].up[l]) u = nodes_[u].up[l], v = nodes_[v].up[l];
  }
  return nodes_[u].up[0];
}

RelativePose TrajectoryTree::fromAncestor(std::uint32_t ancestor, std::uint32_t node) const {
  if (ancestor == node) return {};
  // T_node = T_ancestor T_a_n, so xi_node = Ad(T_a_n^-1) xi_ancestor + xi_a_n: the
  // path below the ancestor is what the node's covariance adds to the ancestor's.
  const Node& a = nodes_[ancestor];
  const Node& n = nodes_[node];
  const Eigen::Isometry3d T_a_n = a.T_origin_k.inverse() * n.T_origin_k;
  return {T_a_n, n.covariance - transportedSymmetric(core::adjoint(T_a_n.inverse()), a.covariance)};
}

RelativePose TrajectoryTree::relative(core::KeyframeId i, core::KeyframeId j) const {
  refresh();
  const std::uint32_t ni = nodeOf(i);
  const std::uint32_t nj = nodeOf(j);
  if (ni == nj) return {};
  const std::uint32_t c = lowestCommonAncestor(ni, nj);
  const RelativePose i_c = inverted(fromAncestor(c, ni));
  const RelativePose c_j = fromAncestor(c, nj);
  return {
      i_c.T_i_j * c_j.T_i_j,
      transportedSymmetric(core::adjoint(c_j.T_i_j.inverse()), i_c.covariance) + c_j.covariance};
}

}  // namespace dcl::backend
