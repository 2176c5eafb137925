#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include <dcl/backend/distributed_refine.hpp>
#include <dcl/core/error.hpp>

#include "pose_block_solver.hpp"

namespace dcl::backend {
namespace {

using PoseMap = std::map<core::PoseKey, Eigen::Isometry3d>;

/// Levenberg-Marquardt iterations at most for a robot that solves its block alone.
constexpr int kAloneIterations = 100;

void require(bool ok, const char* field, const std::string& what) {
  if (!ok) throw core::Error(std::string("refine config: ") + field + " " + what);
}

bool nonNegative(double value) {
  return std::isfinite(value) && value >= 0.0;
}

/// The local graph of every robot: its nodes, every factor touching one of
/// them whose two ends the graph holds, the neighbours' nodes those factors
/// name, and its fixed nodes; the gauge node when the graph fixes none.
std::map<core::RobotId, PoseGraph> localGraphs(const PoseGraph& graph) {
  std::map<core::RobotId, PoseGraph> locals;
  for (const auto& [key, pose] : graph.nodes()) locals[key.robot].addNode(key, pose);
  for (const Factor& f : graph.factors()) {
    if (!graph.connects(f)) continue;
    locals[f.from.robot].addFactor(f);
    if (f.to.robot == f.from.robot) continue;
    // Each side starts from the other's separator as the graph holds it.
    locals[f.to.robot].addFactor(f);
    locals[f.from.robot].addNode(f.to, graph.estimate(f.to));
    locals[f.to.robot].addNode(f.from, graph.estimate(f.from));
  }
  for (const core::PoseKey& key : graph.fixedNodes()) {
    if (graph.hasNode(key)) locals[key.robot].fix(key);
  }
  if (graph.fixedNodes().empty() && graph.size() > 0) {
    const core::PoseKey& lowest = graph.nodes().begin()->first;
    locals[lowest.robot].fix(lowest);
  }
  return locals;
}

}  // namespace

void validate(const RefineConfig& config) {
  require(config.max_rounds >= 0, "max_rounds",
          "must be at least 0, got " + std::to_string(config.max_rounds));
  require(nonNegative(config.relative_tolerance), "relative_tolerance",
          "must be finite and at least 0, got " + std::to_string(config.relative_tolerance));
  require(config.window >= 1, "window", "must be at least 1, got " + std::to_string(config.window));
  require(config.block_iterations >= 1, "block_iterations",
          "must be at least 1, got " + std::to_string(config.block_iterations));
  require(config.factorisation_reuse >= 0, "factorisation_reuse",
          "must be at least 0, got " + std::to_string(config.factorisation_reuse));
  require(nonNegative(config.block_tolerance), "block_tolerance",
          "must be finite and at least 0, got " + std::to_string(config.block_tolerance));
}

struct RefineAgent::Impl {
  core::RobotId robot;
  RefineConfig config;
  detail::PoseBlockSolver problem;  // own poses free, neighbours' separators constant
  std::vector<Factor> pending;      // inter-robot factors whose neighbour pose has no value yet
  std::map<core::RobotId, std::set<core::PoseKey>> separators;
  std::set<core::PoseKey> neighbour_poses;
  std::set<core::PoseKey> held;             // own poses that hold the gauge
  std::set<core::PoseKey> held_neighbours;  // neighbours' poses fixed in `local`: never sent for
  PoseMap estimates;                        // latest: this round's after step()
  PoseMap kept;                             // the last kept round's
  PoseMap kept_before;
  PoseMap neighbours_kept;  // neighbours' separators as of the last kept round
  PoseMap neighbours_kept_before;
  PoseMap received;            // neighbours' separators sent in this round
  std::vector<Factor> active;  // the factors in the problem

  Impl(core::RobotId robot_id, const PoseGraph& local, const RefineConfig& refine_config)
      : robot(robot_id), config(refine_config) {
    validate(config);
    for (const auto& [key, pose] : local.nodes()) {
      if (key.robot == robot) estimates.emplace(key, pose);
      if (key.robot != robot && local.isFixed(key)) held_neighbours.insert(key);
    }
    for (const Factor& f : local.factors()) addFactor(f);
    for (const auto& [key, pose] : local.nodes()) {
      if (own(key) || neighbour_poses.contains(key) || held_neighbours.contains(key))
        problem.setPose(key, pose);
      if (neighbour_poses.contains(key)) neighbours_kept.emplace(key, pose);
    }
    chooseGauge(local);
    activatePending();
    kept = kept_before = estimates;
    neighbours_kept_before = neighbours_kept;
  }

  [[nodiscard]] bool own(const core::PoseKey& key) const { return key.robot == robot; }

  /// Keeps the factors with an own end that is a node; notes the separators.
  void addFactor(const Factor& f) {
    const bool from_own = own(f.from);
    const bool to_own = own(f.to);
    if ((from_own && !estimates.contains(f.from)) || (to_own && !estimates.contains(f.to))) return;
    if ((!from_own && !to_own) || f.from == f.to) return;  // not this block's, or a constant
    if (from_own != to_own) {
      const core::PoseKey& mine = from_own ? f.from : f.to;
      const core::PoseKey& theirs = from_own ? f.to : f.from;
      if (!held_neighbours.contains(theirs)) {
        separators[theirs.robot].insert(mine);
        neighbour_poses.insert(theirs);
      }
    }
    pending.push_back(f);
  }

  /// Adds the factors whose two ends now have values; neighbours' poses and
  /// the gauge stay constant.
  void activatePending() {
    std::erase_if(pending, [this](const Factor& f) {
      if (!problem.addFactor(f)) return false;
      active.push_back(f);
      for (const core::PoseKey& end : {f.from, f.to}) {
        if (!own(end) || held.contains(end)) problem.setConstant(end);
      }
      return true;
    });
  }

  /// The own fixed nodes; with none and no neighbour to pin the block, the
  /// lowest own node a factor between own nodes touches.
  void chooseGauge(const PoseGraph& local) {
    for (const core::PoseKey& key : local.fixedNodes()) {
      if (own(key) && estimates.contains(key)) held.insert(key);
    }
    if (!held.empty() || !neighbour_poses.empty() || !held_neighbours.empty()) return;
    std::set<core::PoseKey> touched;
    for (const Factor& f : pending) touched.insert({f.from, f.to});
    if (!touched.empty()) held.insert(*touched.begin());
  }

  /// Sets every pose of `last` in the problem, moved on by `momentum` along its
  /// geodesic from `before` (where `before` holds it).
  void startFrom(const PoseMap& before, const PoseMap& last, double momentum) {
    for (const auto& [key, pose] : last) {
      const auto it = before.find(key);
      const bool extrapolate = momentum > 0.0 && it != before.end() &&
                               (own(key) ? problem.isVariable(key) : problem.hasPose(key));
      problem.setPose(
          key, extrapolate ? core::interpolateGeodesic(it->second, pose, 1.0 + momentum) : pose);
    }
  }

  void beginRound(double momentum) {
    received.clear();
    startFrom(kept_before, kept, momentum);
    startFrom(neighbours_kept_before, neighbours_kept, momentum);
  }

  void receive(const PoseMap& poses) {
    for (const auto& [key, pose] : poses) {
      if (!neighbour_poses.contains(key)) continue;
      received.insert_or_assign(key, pose);
      problem.setPose(key, pose);
    }
    activatePending();
  }

  void solve(RefineStep& step) {
    if (problem.factors() == 0) return;
    detail::BlockSolveOptions options;
    // A robot no inter-robot factor joins has nothing to wait for: its block
    // is the whole problem of its group, solved to convergence at once.
    options.max_iterations = neighbour_poses.empty()
                                 ? std::max(config.block_iterations, kAloneIterations)
                                 : config.block_iterations;
    options.function_tolerance = config.block_tolerance;
    options.factorisation_reuse = config.factorisation_reuse;
    const detail::BlockSolveSummary summary = problem.solve(options);
    step.cost_before = summary.initial_cost;
    step.cost_after = summary.final_cost;
    step.iterations = summary.iterations;
    for (auto& [key, pose] : estimates) {
      if (problem.isVariable(key)) pose = problem.pose(key);
    }
  }

  [[nodiscard]] double ownedCost() const {
    double cost = 0.0;
    for (const Factor& f : active) {
      const bool held_end = held_neighbours.contains(f.from) || held_neighbours.contains(f.to);
      if (std::min(f.from.robot, f.to.robot) != robot && !held_end) continue;
      const core::Vector6d r = factorResidual(f, problem.pose(f.from), problem.pose(f.to));
      cost += r.dot(f.information * r);
    }
    return cost;
  }

  [[nodiscard]] std::map<core::RobotId, PoseMap> outgoing() const {
    std::map<core::RobotId, PoseMap> messages;
    for (const auto& [neighbour, keys] : separators) {
      PoseMap& poses = messages[neighbour];
      for (const core::PoseKey& key : keys) poses.emplace(key, estimates.at(key));
    }
    return messages;
  }

  void endRound(bool keep) {
    if (!keep) {
      estimates = kept;
    } else {
      kept_before = std::exchange(kept, estimates);
      neighbours_kept_before = neighbours_kept;
      for (const auto& [key, pose] : received) neighbours_kept.insert_or_assign(key, pose);
    }
    received.clear();
  }
};

RefineAgent::RefineAgent(core::RobotId robot, const PoseGraph& local, const RefineConfig& config)
    : impl_(std::make_unique<Impl>(robot, local, config)) {}
RefineAgent::~RefineAgent() = default;
RefineAgent::RefineAgent(RefineAgent&&) noexcept = default;
RefineAgent& RefineAgent::operator=(RefineAgent&&) noexcept = default;

core::RobotId RefineAgent::robot() const {
  return impl_->robot;
}

std::set<core::RobotId> RefineAgent::neighbours() const {
  std::set<core::RobotId> robots;
  for (const auto& [neighbour, keys] : impl_->separators) robots.insert(neighbour);
  return robots;
}

const std::map<core::RobotId, std::set<core::PoseKey>>& RefineAgent::separators() const {
  return impl_->separators;
}

const std::set<core::PoseKey>& RefineAgent::neighbourPoses() const {
  return impl_->neighbour_poses;
}

void RefineAgent::beginRound(double momentum) {
  impl_->beginRound(momentum);
}

void RefineAgent::receive(const PoseMap& neighbour_poses) {
  impl_->receive(neighbour_poses);
}

RefineStep RefineAgent::step() {
  RefineStep step;
  impl_->solve(step);
  step.outgoing = impl_->outgoing();
  return step;
}

void RefineAgent::endRound(bool keep) {
  impl_->endRound(keep);
}

const PoseMap& RefineAgent::estimates() const {
  return impl_->estimates;
}

const PoseMap& RefineAgent::neighbourValues() const {
  return impl_->neighbours_kept;
}

double RefineAgent::ownedCost() const {
  return impl_->ownedCost();
}

namespace {

using Agents = std::map<core::RobotId, RefineAgent>;

/// One round: every robot steps in id order, its separators delivered at once
/// (Gauss-Seidel), its estimates written into `graph`; returns the graph's cost.
double runRound(Agents& agents, PoseGraph& graph, double momentum, RefineSummary& summary) {
  for (auto& [robot, agent] : agents) agent.beginRound(momentum);
  for (auto& [robot, agent] : agents) {
    const RefineStep step = agent.step();
    for (const auto& [neighbour, poses] : step.outgoing) {
      agents.at(neighbour).receive(poses);
      summary.values_sent[robot] += poses.size();
      summary.separator_values += poses.size();
    }
    for (const auto& [key, pose] : agent.estimates()) graph.setEstimate(key, pose);
  }
  ++summary.rounds;
  return graphCost(graph);
}

/// Ends the round for every agent; an undone round's estimates leave `graph` too.
void endRound(Agents& agents, PoseGraph& graph, bool keep) {
  for (auto& [robot, agent] : agents) {
    agent.endRound(keep);
    if (!keep) {
      for (const auto& [key, pose] : agent.estimates()) graph.setEstimate(key, pose);
    }
  }
}

/// True when the kept cost fell by less than the tolerance per round, relatively,
/// on average over the last `window` kept rounds (fewer at the start).
bool stalled(const std::vector<double>& kept_costs, const RefineConfig& config) {
  const std::size_t last = kept_costs.size() - 1;
  const std::size_t rounds = std::min<std::size_t>(last, config.window);
  const double fall = kept_costs[last - rounds] - kept_costs[last];
  return fall <= config.relative_tolerance * static_cast<double>(rounds) * kept_costs[last];
}

/// Nesterov's sequence: t' = (1 + sqrt(1 + 4 t^2)) / 2, momentum (t - 1) / t'.
double nextNesterov(double t) {
  return 0.5 * (1.0 + std::sqrt(1.0 + 4.0 * t * t));
}

}  // namespace

RefineSchedule::RefineSchedule(const RefineConfig& config, double initial_cost)
    : config_(config), kept_costs_{initial_cost} {
  validate(config_);
}

double RefineSchedule::momentum() const {
  return (t_ - 1.0) / (config_.accelerate ? nextNesterov(t_) : 1.0);
}

bool RefineSchedule::endRound(double cost) {
  const double momentum_used = momentum();
  const bool keep = cost <= kept_costs_.back();
  if (keep) {
    kept_costs_.push_back(cost);
    converged_ = stalled(kept_costs_, config_);
    t_ = config_.accelerate ? nextNesterov(t_) : 1.0;
  } else if (momentum_used > 0.0) {
    ++restarts_;  // the momentum overshot: the next round starts without it
    t_ = 1.0;
  } else {
    converged_ = true;  // not even a plain round descends: rounding noise
  }
  ++rounds_;
  round_costs_.push_back(kept_costs_.back());
  return keep;
}

bool RefineSchedule::done() const {
  return converged_ || rounds_ >= config_.max_rounds;
}

RefineSummary refineDistributed(PoseGraph& graph, const RefineConfig& config) {
  validate(config);
  const auto start = std::chrono::steady_clock::now();
  RefineSummary summary;
  summary.initial_cost = summary.final_cost = graphCost(graph);
  Agents agents;
  for (const auto& [robot, local] : localGraphs(graph)) {
    agents.emplace(robot, RefineAgent(robot, local, config));
    summary.values_sent[robot] = 0;
  }
  RefineSchedule schedule(config, summary.initial_cost);
  while (!schedule.done()) {
    const double cost = runRound(agents, graph, schedule.momentum(), summary);
    endRound(agents, graph, schedule.endRound(cost));
  }
  summary.final_cost = schedule.cost();
  summary.restarts = schedule.restarts();
  summary.round_costs = schedule.roundCosts();
  summary.converged = schedule.converged();
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace dcl::backend
