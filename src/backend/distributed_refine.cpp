#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include <dcl/backend/dgs.hpp>
#include <dcl/backend/distributed_refine.hpp>
#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>

#include "pose_block_solver.hpp"

namespace dcl::backend {
namespace {

using PoseMap = std::map<core::PoseKey, Eigen::Isometry3d>;

/// Levenberg-Marquardt iterations at most for a robot that solves its block alone.
constexpr int kAloneIterations = 100;
/// The local graph of every robot: its nodes, every factor touching one of
/// them whose two ends the graph holds, the neighbours' nodes those factors
/// name, and its fixed nodes.
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
  return locals;
}

}  // namespace

void validate(const RefineConfig& config) {
  core::checkConfig(config, "refine config");
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
  std::vector<detail::RelativePoseMeasurement> measurements;  // of `active`, for coarse terms
  std::optional<CoarseGrid> grid;             // own; none: no coarse motion of own poses
  std::map<core::RobotId, CoarseGrid> grids;  // own and the neighbours' that have one
  CoarseBlocks blocks_shared;                 // the coarse blocks last shared
  // Own separators as the neighbours hold them: as of the last kept round,
  // the round before, and at this round's start (their extrapolation and
  // coarse step of the values held), then what they hold after this round.
  PoseMap told;
  PoseMap told_before;
  PoseMap told_now;
  double block_chi2 = 0.0;  // the block's chi-square a factor after the last step

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
    for (const auto& [neighbour, keys] : separators) {
      for (const core::PoseKey& key : keys) told.emplace(key, estimates.at(key));
    }
    told_before = told_now = told;
    makeGrid();
  }

  /// The own coarse grid over the own poses; none when coarse corrections are
  /// off or a pose of this robot holds the gauge (the block may not move).
  void makeGrid() {
    if (config.coarse_cells == 0 || !held.empty() || estimates.empty()) return;
    std::vector<Eigen::Vector3d> positions;
    for (const auto& [key, T] : estimates) positions.emplace_back(T.translation());
    grid = makeCoarseGrid(positions, config.coarse_cells);
    grids[robot] = *grid;
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
      measurements.emplace_back(f.T_from_to, detail::sqrtInformation(f.information));
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

  void beginRound(double momentum, const CoarseStep* coarse) {
    received.clear();
    startFrom(kept_before, kept, momentum);
    startFrom(neighbours_kept_before, neighbours_kept, momentum);
    if (coarse != nullptr) moveBy(*coarse);
    predictTold(momentum, coarse);
  }

  /// Where the neighbours start this round's copies of the own separators:
  /// what they hold, moved as they move it (startFrom, moveBy).
  void predictTold(double momentum, const CoarseStep* coarse) {
    for (const auto& [key, T] : told) {
      const bool variable = problem.isVariable(key);
      Eigen::Isometry3d start = T;
      if (momentum > 0.0 && variable) {
        start = core::interpolateGeodesic(told_before.at(key), T, 1.0 + momentum);
      }
      if (coarse != nullptr && grid && variable) start = applyCoarse(*coarse, robot, *grid, start);
      told_now.insert_or_assign(key, start);
    }
  }

  /// The own separators whose estimate is further from the neighbours' copy
  /// than separator_tolerance, in some active inter-robot factor's whitened
  /// residual, relative to the block's residual a factor (a graph that fits
  /// its measurements to a tenth of their noise needs its copies ten times
  /// closer); those are sent, and the copies become their estimates.
  [[nodiscard]] std::set<core::PoseKey> moved() {
    std::set<core::PoseKey> keys;
    for (const auto& [key, T] : told_now) {
      if (config.separator_tolerance == 0.0) keys.insert(key);
    }
    const double tolerance2 = config.separator_tolerance * config.separator_tolerance * block_chi2;
    for (const Factor& f : active) {
      if (own(f.from) == own(f.to)) continue;
      const core::PoseKey& mine = own(f.from) ? f.from : f.to;
      const auto it = told_now.find(mine);
      if (it == told_now.end() || keys.contains(mine)) continue;
      const auto residual = [&](const Eigen::Isometry3d& T_mine) {
        return own(f.from) ? factorResidual(f, T_mine, problem.pose(f.to))
                           : factorResidual(f, problem.pose(f.from), T_mine);
      };
      const core::Vector6d d = residual(estimates.at(mine)) - residual(it->second);
      if (d.dot(f.information * d) > tolerance2) keys.insert(mine);
    }
    for (const core::PoseKey& key : keys) told_now.insert_or_assign(key, estimates.at(key));
    return keys;
  }

  /// A pose the coarse step moves: of a robot with a grid, not held.
  [[nodiscard]] bool movable(const core::PoseKey& key) const {
    return grids.contains(key.robot) && !held_neighbours.contains(key) &&
           (own(key) ? problem.isVariable(key) : problem.hasPose(key));
  }

  /// Own poses and the copies of the neighbours' separators moved by the
  /// group's coarse step; the copies count as received in this round.
  void moveBy(const CoarseStep& step) {
    for (const auto& [key, T] : kept) {
      if (movable(key))
        problem.setPose(key, applyCoarse(step, robot, grids.at(robot), problem.pose(key)));
    }
    for (const core::PoseKey& key : neighbour_poses) {
      if (!movable(key)) continue;
      const Eigen::Isometry3d T =
          applyCoarse(step, key.robot, grids.at(key.robot), problem.pose(key));
      problem.setPose(key, T);
      received.insert_or_assign(key, T);
    }
  }

  /// The coarse columns of one end of a factor (none when it does not move).
  void appendColumns(std::vector<CoarseColumn>& columns, const core::Matrix6d& J,
                     const core::PoseKey& key, const Eigen::Isometry3d& T) const {
    if (movable(key)) appendCoarseColumns(columns, J, key.robot, grids.at(key.robot), T);
  }

  /// The share at the current values; its blocks only when they moved by
  /// more than coarse_refresh since the ones last shared (or none were).
  CoarseShare shareCoarse(bool fresh) {
    CoarseShare share = coarseShare(true);
    if (!fresh && !blocks_shared.empty() &&
        relativeChange(share.hessian, blocks_shared) <= config.coarse_refresh) {
      share.hessian.clear();
    } else {
      blocks_shared = share.hessian;
    }
    return share;
  }

  [[nodiscard]] CoarseShare coarseShare(bool hessian) const {
    CoarseShare share{robot, {}, {}};
    std::vector<CoarseColumn> columns;
    for (std::size_t i = 0; i < active.size(); ++i) {
      const Factor& f = active[i];
      if (!owns(f)) continue;
      const Eigen::Isometry3d T_from = problem.pose(f.from);
      const Eigen::Isometry3d T_to = problem.pose(f.to);
      core::Matrix6d J_from;
      core::Matrix6d J_to;
      const core::Vector6d r = measurements[i].linearise(
          Eigen::Quaterniond(T_from.linear()), T_from.translation(),
          Eigen::Quaterniond(T_to.linear()), T_to.translation(), J_from, J_to);
      columns.clear();
      appendColumns(columns, J_from, f.from, T_from);
      appendColumns(columns, J_to, f.to, T_to);
      addToShare(share, r, columns, hessian);
    }
    return share;
  }

  /// A pose as the coarse step `step` moves it.
  [[nodiscard]] Eigen::Isometry3d coarseMoved(const CoarseStep& step,
                                              const core::PoseKey& key) const {
    const Eigen::Isometry3d T = problem.pose(key);
    return movable(key) ? applyCoarse(step, key.robot, grids.at(key.robot), T) : T;
  }

  [[nodiscard]] std::array<double, kCoarseScales.size()> coarseTrialCosts(
      const CoarseStep& step) const {
    std::array<double, kCoarseScales.size()> costs{};
    for (std::size_t k = 0; k < costs.size(); ++k) {
      const CoarseStep trial = scaled(step, kCoarseScales[k]);
      for (const Factor& f : active) {
        if (!owns(f)) continue;
        const core::Vector6d r =
            factorResidual(f, coarseMoved(trial, f.from), coarseMoved(trial, f.to));
        costs[k] += r.dot(f.information * r);
      }
    }
    return costs;
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
    block_chi2 = summary.final_cost / static_cast<double>(problem.factors());
    for (auto& [key, pose] : estimates) {
      if (problem.isVariable(key)) pose = problem.pose(key);
    }
  }

  /// Every factor has one owner: the lower robot of its ends, or the robot
  /// holding a neighbour's pose constant.
  [[nodiscard]] bool owns(const Factor& f) const {
    const bool held_end = held_neighbours.contains(f.from) || held_neighbours.contains(f.to);
    return held_end || std::min(f.from.robot, f.to.robot) == robot;
  }

  [[nodiscard]] double ownedCost() const {
    double cost = 0.0;
    for (const Factor& f : active) {
      if (!owns(f)) continue;
      const core::Vector6d r = factorResidual(f, problem.pose(f.from), problem.pose(f.to));
      cost += r.dot(f.information * r);
    }
    return cost;
  }

  [[nodiscard]] std::map<core::RobotId, PoseMap> outgoing() {
    const std::set<core::PoseKey> sent = moved();
    std::map<core::RobotId, PoseMap> messages;
    for (const auto& [neighbour, keys] : separators) {
      PoseMap& poses = messages[neighbour];
      for (const core::PoseKey& key : keys) {
        if (sent.contains(key)) poses.emplace(key, estimates.at(key));
      }
    }
    return messages;
  }

  void endRound(bool keep) {
    if (!keep) {
      estimates = kept;
    } else {
      kept_before = std::exchange(kept, estimates);
      neighbours_kept_before = neighbours_kept;
      // What was not sent stays where this round started it, on both sides.
      for (auto& [key, pose] : neighbours_kept) {
        if (problem.hasPose(key)) pose = problem.pose(key);
      }
      for (const auto& [key, pose] : received) neighbours_kept.insert_or_assign(key, pose);
      told_before = std::exchange(told, told_now);
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

void RefineAgent::beginRound(double momentum, const CoarseStep* coarse) {
  impl_->beginRound(momentum, coarse);
}

const std::optional<CoarseGrid>& RefineAgent::coarseGrid() const {
  return impl_->grid;
}

void RefineAgent::setCoarseGrid(core::RobotId neighbour, const CoarseGrid& grid) {
  if (neighbour != impl_->robot) impl_->grids[neighbour] = grid;
}

CoarseShare RefineAgent::coarseShare(bool hessian) const {
  return impl_->coarseShare(hessian);
}

CoarseShare RefineAgent::shareCoarse(bool fresh) {
  return impl_->shareCoarse(fresh);
}

std::array<double, kCoarseScales.size()> RefineAgent::coarseTrialCosts(
    const CoarseStep& step) const {
  return impl_->coarseTrialCosts(step);
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

/// What the driver passes along to every round.
struct Run {
  PoseGraph& graph;
  RefineSummary& summary;
  const RefineTraffic& traffic;
  const RefineConfig& config;
};

/// One round: every robot steps in id order, its separators delivered at once
/// (Gauss-Seidel), its estimates written into the graph; then every robot
/// shares its part of the cost. Returns the sum of the shares: the graph's
/// cost at the neighbours' copies of the separators, as the robots know it.
double runRound(Agents& agents, Run& run, double momentum, const CoarseStep* coarse) {
  const int round = ++run.summary.rounds;
  for (auto& [robot, agent] : agents) agent.beginRound(momentum, coarse);
  for (auto& [robot, agent] : agents) {
    const RefineStep step = agent.step();
    for (const auto& [neighbour, poses] : step.outgoing) {
      agents.at(neighbour).receive(poses);
      run.summary.values_sent[robot] += poses.size();
      run.summary.separator_values += poses.size();
      if (run.traffic.separators) run.traffic.separators(robot, neighbour, round, poses);
    }
    for (const auto& [key, pose] : agent.estimates()) run.graph.setEstimate(key, pose);
  }
  double cost = 0.0;
  for (auto& [robot, agent] : agents) {
    const double share = agent.ownedCost();
    if (run.traffic.cost) run.traffic.cost(robot, round, share);
    cost += share;
  }
  return cost;
}

/// The group's coarse step at the kept round's estimates (whose cost is
/// `cost`), from every robot's share, at the length the robots' priced costs
/// choose; `refresh`: every robot sends fresh blocks, and is set for the next
/// step when this one fell short of its model.
CoarseStep coarseStep(Agents& agents, Run& run, CoarseSolver& solver, double cost, bool& refresh) {
  std::vector<CoarseShare> shares;
  for (auto& [robot, agent] : agents) {
    shares.push_back(agent.shareCoarse(refresh));
    ++run.summary.coarse_shares;
    run.summary.coarse_blocks += shares.back().hessian.size();
    if (run.traffic.coarse) run.traffic.coarse(run.summary.rounds, shares.back());
  }
  if (refresh) ++run.summary.coarse_refreshes;
  const CoarseStep step = solver.solve(shares);
  std::array<double, kCoarseScales.size()> costs{};
  for (auto& [robot, agent] : agents) {
    const auto share = agent.coarseTrialCosts(step);
    if (run.traffic.coarse_costs) run.traffic.coarse_costs(robot, run.summary.rounds, share);
    for (std::size_t k = 0; k < costs.size(); ++k) costs[k] += share[k];
  }
  const CoarseChoice choice = coarseScale(step, cost, costs, run.config.coarse_trust);
  refresh = choice.refresh;
  return scaled(step, choice.scale);
}

/// Every robot's grid to each of its neighbours (robots holding the gauge have none).
void shareGrids(Agents& agents, const RefineTraffic& traffic) {
  for (auto& [robot, agent] : agents) {
    if (!agent.coarseGrid()) continue;
    for (const core::RobotId neighbour : agent.neighbours()) {
      agents.at(neighbour).setCoarseGrid(robot, *agent.coarseGrid());
      if (traffic.grid) traffic.grid(robot, neighbour, *agent.coarseGrid());
    }
  }
}

/// The separators every robot's neighbours start from (sent before the first step).
void announceStart(const Agents& agents, const RefineTraffic& traffic) {
  if (!traffic.separators) return;
  for (const auto& [robot, agent] : agents) {
    for (const auto& [neighbour, keys] : agent.separators()) {
      RefineTraffic::Poses poses;
      for (const core::PoseKey& key : keys) poses.emplace(key, agent.estimates().at(key));
      traffic.separators(robot, neighbour, 0, poses);
    }
  }
}

/// Where the lowest node of every group of connected robots without a fixed
/// node starts: it is put back there at the end (the gauge).
std::map<core::PoseKey, Eigen::Isometry3d> floatingAnchors(const PoseGraph& graph) {
  std::map<core::PoseKey, Eigen::Isometry3d> anchors;
  for (const std::set<core::RobotId>& group : connectedGroups(graph)) {
    const auto in = [&](const core::PoseKey& key) { return group.contains(key.robot); };
    const auto& fixed = graph.fixedNodes();
    if (std::any_of(fixed.begin(), fixed.end(), in)) continue;
    for (const auto& [key, T] : graph.nodes()) {
      if (!in(key)) continue;
      anchors.emplace(key, T);
      break;
    }
  }
  return anchors;
}

/// Moves each floating group rigidly so that its lowest node is back where it started.
void reanchor(PoseGraph& graph, const std::map<core::PoseKey, Eigen::Isometry3d>& anchors) {
  for (const auto& [anchor, T_start] : anchors) {
    const Eigen::Isometry3d G = T_start * graph.estimate(anchor).inverse();
    std::set<core::RobotId> group;
    for (const std::set<core::RobotId>& g : connectedGroups(graph)) {
      if (g.contains(anchor.robot)) group = g;
    }
    for (const auto& [key, T] : graph.nodes()) {
      if (group.contains(key.robot)) graph.setEstimate(key, G * T);
    }
  }
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

bool RefineSchedule::endRound(double cost, bool coarse) {
  const bool plain = momentum() == 0.0 && !coarse;
  const bool keep = cost <= kept_costs_.back();
  if (keep) {
    kept_costs_.push_back(cost);
    converged_ = stalled(kept_costs_, config_);
    t_ = config_.accelerate ? nextNesterov(t_) : 1.0;
  } else if (!plain) {
    ++restarts_;  // momentum or the coarse step overshot: the next round starts without both
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

RefineSummary refineDistributed(PoseGraph& graph, const RefineConfig& config,
                                const RefineTraffic& traffic) {
  validate(config);
  const auto start = std::chrono::steady_clock::now();
  RefineSummary summary;
  summary.initial_cost = summary.final_cost = graphCost(graph);
  const auto anchors = floatingAnchors(graph);
  Agents agents;
  for (const auto& [robot, local] : localGraphs(graph)) {
    agents.emplace(robot, RefineAgent(robot, local, config));
    summary.values_sent[robot] = 0;
  }
  shareGrids(agents, traffic);
  announceStart(agents, traffic);
  Run run{graph, summary, traffic, config};
  RefineSchedule schedule(config, summary.initial_cost);
  CoarseSolver solver;  // one for all: every robot's copy takes the same steps
  std::optional<CoarseStep> coarse;
  bool refresh = false;  // the last coarse step fell short of its model
  while (!schedule.done()) {
    const double cost = runRound(agents, run, schedule.momentum(), coarse ? &*coarse : nullptr);
    const bool keep = schedule.endRound(cost, coarse.has_value());
    coarse.reset();
    if (keep && config.coarse_cells > 0) coarse = coarseStep(agents, run, solver, cost, refresh);
    endRound(agents, graph, keep);
  }
  reanchor(graph, anchors);
  summary.final_cost = schedule.cost();
  summary.restarts = schedule.restarts();
  summary.round_costs = schedule.roundCosts();
  summary.converged = schedule.converged();
  summary.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace dcl::backend
