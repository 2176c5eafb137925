#include <Eigen/Cholesky>
#include <algorithm>
#include <string>

#include <fmt/format.h>

#include <dcl/backend/pcm.hpp>
#include <dcl/core/error.hpp>

namespace dcl::backend {
namespace {

/// Smallest eigenvalue a cycle's covariance is given when rounding made it indefinite.
constexpr double kMinVariance = 1e-12;

/// A Sigma A^T.
core::Matrix6d transported(const core::Matrix6d& A, const core::Matrix6d& sigma) {
  return A * sigma * A.transpose();
}

core::Matrix6d symmetric(const core::Matrix6d& m) {
  return 0.5 * (m + m.transpose());
}

/// r^T Sigma^-1 r; a covariance that lost definiteness to rounding is clamped.
double mahalanobisSquared(const core::Vector6d& r, const core::Matrix6d& sigma) {
  const Eigen::LDLT<core::Matrix6d> ldlt(sigma);
  if (ldlt.info() == Eigen::Success && ldlt.isPositive() && ldlt.vectorD().minCoeff() > 0.0) {
    return r.dot(ldlt.solve(r));
  }
  return r.dot(informationFromCovariance(sigma, kMinVariance) * r);
}

/// Eq. 8 on measurements: the cycle X1 X2 X3 X4 = z_ik T_{b_k b_l} z_jl^-1 T_{a_j a_i}.
/// With right perturbations, X1 exp(e1) X2 exp(e2) X3 exp(e3) X4 exp(e4) is
/// T exp(J1 e1 + J2 e2 + J3 e3 + e4), J1 = Ad((X2 X3 X4)^-1), J2 = Ad((X3 X4)^-1),
/// J3 = Ad(X4^-1).
double cycleMahalanobis(const Eigen::Isometry3d& z_ik, const core::Matrix6d& sigma_ik,
                        const Eigen::Isometry3d& z_jl, const core::Matrix6d& sigma_jl_inverse,
                        const RelativePose& b_kl, const RelativePose& a_ji) {
  const Eigen::Isometry3d X34 = z_jl.inverse() * a_ji.T_i_j;
  const Eigen::Isometry3d X234 = b_kl.T_i_j * X34;
  const core::Matrix6d sigma = transported(core::adjoint(X234.inverse()), sigma_ik) +
                               transported(core::adjoint(X34.inverse()), b_kl.covariance) +
                               transported(core::adjoint(a_ji.T_i_j.inverse()), sigma_jl_inverse) +
                               a_ji.covariance;
  return mahalanobisSquared(core::logSE3(z_ik * X234), sigma);
}

}  // namespace

Factor invertFactor(const Factor& factor) {
  const core::Matrix6d ad_inverse = core::adjoint(factor.T_from_to.inverse());
  return {factor.to, factor.from, factor.T_from_to.inverse(),
          symmetric(ad_inverse.transpose() * factor.information * ad_inverse), factor.kind};
}

double cycleDistance(const Factor& loop_1, const Factor& loop_2, const TrajectoryTree& robot_a,
                     const TrajectoryTree& robot_b) {
  for (const Factor* loop : {&loop_1, &loop_2}) {
    if (loop->from.robot != robot_a.robot() || loop->to.robot != robot_b.robot()) {
      throw core::Error(fmt::format("PCM: loop {} -> {} is not from robot {} to robot {}",
                                    core::keyName(loop->from), core::keyName(loop->to),
                                    core::robotName(robot_a.robot()),
                                    core::robotName(robot_b.robot())));
    }
  }
  const core::Matrix6d sigma_2 = covarianceOf(loop_2.information);
  return cycleMahalanobis(loop_1.T_from_to, covarianceOf(loop_1.information), loop_2.T_from_to,
                          transported(core::adjoint(loop_2.T_from_to), sigma_2),
                          robot_b.relative(loop_1.to.keyframe, loop_2.to.keyframe),
                          robot_a.relative(loop_2.from.keyframe, loop_1.from.keyframe));
}

// ---------------------------------------------------------------------------
// PairwiseConsistency

PairwiseConsistency::PairwiseConsistency(core::RobotId a, core::RobotId b, const PcmConfig& config)
    : PairwiseConsistency(TrajectoryTree(a, core::KeyframeId(0), config.intra_loops),
                          TrajectoryTree(b, core::KeyframeId(0), config.intra_loops), config) {}

PairwiseConsistency::PairwiseConsistency(TrajectoryTree a, TrajectoryTree b,
                                         const PcmConfig& config)
    : config_(config), robot_a_(std::move(a)), robot_b_(std::move(b)) {
  if (robot_a_.robot() == robot_b_.robot()) {
    throw core::Error("PCM needs two different robots, got " + core::robotName(robot_a_.robot()) +
                      " twice");
  }
  if (robot_b_.robot() < robot_a_.robot()) std::swap(robot_a_, robot_b_);
}

void PairwiseConsistency::addRobotFactor(const Factor& factor) {
  TrajectoryTree& robot = factor.from.robot == robot_a_.robot() ? robot_a_ : robot_b_;
  robot.add(factor);  // throws for a third robot's factor
  decided_ = false;   // a loop may be reached, or the trees changed
}

PairwiseConsistency::Candidate PairwiseConsistency::candidateOf(const Factor& loop) const {
  const LoopId id = loopId(loop);
  if (id.first.robot != robot_a_.robot() || id.second.robot != robot_b_.robot()) {
    throw core::Error(fmt::format(
        "PCM {}-{}: loop {} -> {} is not between these robots", core::robotName(robot_a_.robot()),
        core::robotName(robot_b_.robot()), core::keyName(loop.from), core::keyName(loop.to)));
  }
  Candidate c{loop.from.robot == robot_a_.robot() ? loop : invertFactor(loop),
              core::Matrix6d::Zero(), core::Matrix6d::Zero(), std::nullopt};
  c.covariance = covarianceOf(c.loop.information);
  c.inverse_covariance = transported(core::adjoint(c.loop.T_from_to), c.covariance);
  return c;
}

bool PairwiseConsistency::addLoop(const Factor& loop) {
  const LoopId id = loopId(loop);
  if (index_.contains(id)) return false;  // held loops are all between these robots
  candidates_.push_back(candidateOf(loop));
  index_.emplace(id, candidates_.size() - 1);
  decided_ = false;
  syncTrajectories();
  if (!withdrawn_.contains(id) && reachable(candidates_.back().loop)) check(candidates_.size() - 1);
  return true;
}

bool PairwiseConsistency::withdraw(const LoopId& id) {
  if (!withdrawn_.insert(id).second) return false;
  const auto it = index_.find(id);
  if (it != index_.end() && candidates_[it->second].vertex) resetChecks();
  decided_ = false;
  return true;
}

bool PairwiseConsistency::replaceLoop(const Factor& loop) {
  Candidate c = candidateOf(loop);
  const auto it = index_.find(loopId(loop));
  if (it == index_.end()) return false;
  candidates_[it->second] = std::move(c);
  resetChecks();
  decided_ = false;
  return true;
}

bool PairwiseConsistency::reachable(const Factor& loop) const {
  return robot_a_.reaches(loop.from.keyframe) && robot_b_.reaches(loop.to.keyframe);
}

void PairwiseConsistency::syncTrajectories() {
  const std::pair revisions{robot_a_.revision(), robot_b_.revision()};
  if (revisions == revisions_) return;
  // Relative poses changed: every pair is checked again.
  revisions_ = revisions;
  resetChecks();
}

void PairwiseConsistency::resetChecks() {
  for (Candidate& c : candidates_) c.vertex.reset();
  vertex_candidate_.clear();
  graph_ = AdjacencyGraph();
  edges_ = 0;
  decided_vertices_ = 0;
}

void PairwiseConsistency::check(std::size_t index) {
  Candidate& added = candidates_[index];
  const std::size_t v = graph_.addVertex();
  vertex_candidate_.push_back(index);
  added.vertex = v;
  const LoopId added_id = loopId(added.loop);
  for (std::size_t u = 0; u < v; ++u) {
    const Candidate& other = candidates_[vertex_candidate_[u]];
    // Always in key order, so that both robots evaluate the same expression.
    const bool other_first = loopId(other.loop) < added_id;
    const double d = other_first ? distance(other, added) : distance(added, other);
    if (d <= config_.threshold) {
      graph_.addEdge(u, v);
      ++edges_;
    }
  }
}

double PairwiseConsistency::distance(const Candidate& first, const Candidate& second) const {
  return cycleMahalanobis(first.loop.T_from_to, first.covariance, second.loop.T_from_to,
                          second.inverse_covariance,
                          robot_b_.relative(first.loop.to.keyframe, second.loop.to.keyframe),
                          robot_a_.relative(second.loop.from.keyframe, first.loop.from.keyframe));
}

std::vector<std::size_t> PairwiseConsistency::canonicalOrder() const {
  std::vector<std::size_t> order;  // graph vertices by loop key
  order.reserve(graph_.size());
  for (const auto& [id, index] : index_) {
    if (candidates_[index].vertex) order.push_back(*candidates_[index].vertex);
  }
  return order;
}

bool PairwiseConsistency::cliqueUnchanged() const {
  // A clique through a new vertex has at most degree + 1 members: when that is
  // below the clique's size for every new vertex, the maximum cliques are the
  // old ones, and so is the lexicographically smallest (old vertices keep
  // their relative key order).
  if (decided_vertices_ == 0 || !decision_.exact) return false;
  for (std::size_t v = decided_vertices_; v < graph_.size(); ++v) {
    if (graph_.degree(v) + 1 >= clique_size_) return false;
  }
  return true;
}

void PairwiseConsistency::solve() {
  const std::vector<std::size_t> order = canonicalOrder();
  const CliqueResult clique =
      maximumClique(graph_.permuted(order), {.max_exact_vertices = config_.max_exact_loops,
                                             .max_branch_nodes = config_.max_branch_nodes});
  accepted_.assign(graph_.size(), false);
  for (std::size_t k : clique.vertices) accepted_[order[k]] = true;
  decision_.exact = clique.exact;
  clique_size_ = clique.vertices.size();
  decided_vertices_ = graph_.size();
}

const PcmDecision& PairwiseConsistency::decide() {
  if (decided_) return decision_;
  syncTrajectories();
  for (std::size_t i = 0; i < candidates_.size(); ++i) {
    const Candidate& c = candidates_[i];
    if (!c.vertex && !withdrawn_.contains(loopId(c.loop)) && reachable(c.loop)) check(i);
  }
  if (cliqueUnchanged()) {
    accepted_.resize(graph_.size(), false);
  } else {
    solve();
  }
  decision_.accepted.clear();
  decision_.rejected.clear();
  decision_.unverified.clear();
  decision_.withdrawn.clear();
  for (const auto& [id, index] : index_) {
    const Candidate& c = candidates_[index];
    if (withdrawn_.contains(id)) {
      decision_.withdrawn.push_back(c.loop);
    } else if (!c.vertex) {
      decision_.unverified.push_back(c.loop);
    } else {
      (accepted_[*c.vertex] ? decision_.accepted : decision_.rejected).push_back(c.loop);
    }
  }
  decision_.too_few = !decision_.accepted.empty() && decision_.accepted.size() < config_.min_loops;
  if (decision_.too_few) {
    decision_.unverified.insert(decision_.unverified.end(), decision_.accepted.begin(),
                                decision_.accepted.end());
    decision_.accepted.clear();
  }
  decision_.consistent_pairs = edges_;
  decided_ = true;
  return decision_;
}

std::vector<Factor> PairwiseConsistency::loops() const {
  std::vector<Factor> out;
  out.reserve(candidates_.size());
  for (const Candidate& c : candidates_) out.push_back(c.loop);
  return out;
}

// ---------------------------------------------------------------------------
// Whole graphs

std::size_t PcmResult::loops() const {
  std::size_t n = 0;
  for (const auto& p : pairs) {
    n += p.decision.accepted.size() + p.decision.rejected.size() + p.decision.unverified.size() +
         p.decision.withdrawn.size();
  }
  return n;
}

std::size_t PcmResult::accepted() const {
  std::size_t n = 0;
  for (const auto& p : pairs) n += p.decision.accepted.size();
  return n;
}

std::vector<LoopId> PcmResult::acceptedIds() const {
  std::vector<LoopId> ids;
  for (const auto& p : pairs) {
    for (const Factor& f : p.decision.accepted) ids.push_back(loopId(f));
  }
  std::sort(ids.begin(), ids.end());
  return ids;
}

PcmResult runPcm(const PoseGraph& graph, const PcmConfig& config) {
  std::map<core::RobotId, std::uint64_t> origin;  // each robot's lowest keyframe
  const auto see = [&](const core::PoseKey& key) {
    const auto [it, added] = origin.emplace(key.robot, key.keyframe.value());
    if (!added) it->second = std::min(it->second, key.keyframe.value());
  };
  for (const auto& [key, pose] : graph.nodes()) see(key);
  std::map<core::RobotId, std::vector<const Factor*>> local;  // odometry and intra-robot loops
  std::map<std::pair<core::RobotId, core::RobotId>, std::vector<const Factor*>> loops;
  for (const Factor& f : graph.factors()) {
    see(f.from);
    see(f.to);
    if (f.from.robot != f.to.robot) {
      const LoopId id = loopId(f);
      loops[{id.first.robot, id.second.robot}].push_back(&f);
    } else {
      local[f.from.robot].push_back(&f);
    }
  }
  PcmResult result;
  for (const auto& [robots, pair_loops] : loops) {
    const auto tree = [&](core::RobotId r) {
      TrajectoryTree t(r, core::KeyframeId(origin[r]), config.intra_loops);
      for (const Factor* f : local[r]) t.add(*f);
      return t;
    };
    PairwiseConsistency pcm(tree(robots.first), tree(robots.second), config);
    for (const Factor* f : pair_loops) pcm.addLoop(*f);
    result.pairs.push_back({robots.first, robots.second, pcm.decide()});
  }
  return result;
}

}  // namespace dcl::backend
