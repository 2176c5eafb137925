#include <algorithm>
#include <map>
#include <set>

#include <dcl/backend/loop_check.hpp>

namespace dcl::backend {
namespace {

/// The robot pair of a loop, lower first.
std::pair<core::RobotId, core::RobotId> pairOf(const LoopId& id) {
  return {id.first.robot, id.second.robot};
}

/// `graph` without the inter-robot loops in `withdrawn`, each robot's own
/// factors weighted `stiffness` times.
PoseGraph withoutLoops(const PoseGraph& graph, const std::set<LoopId>& withdrawn,
                       double stiffness) {
  PoseGraph out;
  for (const auto& [key, T] : graph.nodes()) out.addNode(key, T);
  for (const core::PoseKey& key : graph.fixedNodes()) out.fix(key);
  for (Factor f : graph.factors()) {
    if (f.from.robot != f.to.robot) {
      if (withdrawn.contains(loopId(f))) continue;
    } else {
      f.information *= stiffness;
    }
    out.addFactor(f);
  }
  return out;
}

/// The inter-robot loops of `graph`.
std::vector<Factor> interRobotLoops(const PoseGraph& graph) {
  std::vector<Factor> loops;
  for (const Factor& f : graph.factors())
    if (f.from.robot != f.to.robot) loops.push_back(f);
  return loops;
}

}  // namespace

std::vector<LoopResidual> loopResiduals(const std::vector<Factor>& loops, const PoseLookup& poses) {
  std::vector<LoopResidual> residuals;
  for (const Factor& f : loops) {
    const std::optional<Eigen::Isometry3d> from = poses(f.from);
    const std::optional<Eigen::Isometry3d> to = poses(f.to);
    if (!from || !to) continue;
    const core::Vector6d r = factorResidual(f, *from, *to);
    residuals.push_back({loopId(f), r.dot(f.information * r)});
  }
  return residuals;
}

std::optional<Unexplained> worstUnexplained(const std::vector<LoopResidual>& residuals,
                                            const LoopCheckConfig& config) {
  if (!config.enabled) return std::nullopt;
  const auto worst = std::max_element(
      residuals.begin(), residuals.end(),
      [](const LoopResidual& a, const LoopResidual& b) { return a.chi2 < b.chi2; });
  if (worst == residuals.end() || !(worst->chi2 > config.threshold)) return std::nullopt;
  Unexplained out{pairOf(worst->id), {}, worst->chi2};
  for (const LoopResidual& r : residuals)
    if (pairOf(r.id) == out.robots && r.chi2 > config.threshold) out.loops.push_back(r.id);
  std::sort(out.loops.begin(), out.loops.end());
  return out;
}

std::vector<LoopId> withdrawUnexplained(PoseGraph& graph, const LoopCheckConfig& config,
                                        const SolverConfig& solver) {
  // The graph without `out`, solved with stiff odometry: its worst loop's
  // chi-square and its cost.
  struct Trial {
    PoseGraph solved;
    std::vector<LoopResidual> residuals;
    double cost = 0.0;
  };
  const auto trial = [&](const std::set<LoopId>& out) {
    Trial t{withoutLoops(graph, out, config.odometry_stiffness), {}, 0.0};
    t.cost = solveCentralized(t.solved, solver).final_cost;
    const PoseGraph& solved = t.solved;
    t.residuals = loopResiduals(interRobotLoops(solved), [&](const core::PoseKey& key) {
      return solved.hasNode(key) ? std::optional(solved.estimate(key)) : std::nullopt;
    });
    return t;
  };
  std::vector<LoopId> withdrawn;
  std::set<LoopId> out;
  Trial now = trial(out);
  while (const std::optional<Unexplained> worst = worstUnexplained(now.residuals, config)) {
    // Every cycle the unexplained loops close could be opened at any of its
    // robot pairs. Open it at the pair with the least support: the fewest
    // unexplained loops whose withdrawal leaves every other loop explained,
    // the lowest cost among pairs that tie; failing any, the worst loop's
    // pair's unexplained loops.
    std::map<std::pair<core::RobotId, core::RobotId>, std::vector<LoopId>> pairs;
    for (const LoopResidual& r : now.residuals)
      if (r.chi2 > config.threshold) pairs[pairOf(r.id)].push_back(r.id);
    std::vector<std::pair<std::size_t, std::pair<core::RobotId, core::RobotId>>> by_support;
    for (const auto& [robots, ids] : pairs) by_support.emplace_back(ids.size(), robots);
    std::sort(by_support.begin(), by_support.end());
    std::vector<LoopId> chosen = worst->loops;
    std::optional<Trial> best;
    std::size_t best_support = 0;
    if (pairs.size() == 1) by_support.clear();  // nothing to choose between
    for (const auto& [support, robots] : by_support) {
      if (best && support > best_support) break;
      std::set<LoopId> without = out;
      without.insert(pairs[robots].begin(), pairs[robots].end());
      Trial t = trial(without);
      if (worstUnexplained(t.residuals, config) || (best && !(t.cost < best->cost))) continue;
      chosen = pairs[robots];
      best_support = support;
      best = std::move(t);
    }
    for (const LoopId& id : chosen) {
      out.insert(id);
      withdrawn.push_back(id);
    }
    now = best ? std::move(*best) : trial(out);
  }
  PoseGraph kept = withoutLoops(graph, out, 1.0);
  solveCentralized(kept, solver);
  graph = std::move(kept);
  return withdrawn;
}

std::size_t checkKeptLoops(const PoseGraph& graph, PcmResult& result,
                           const LoopCheckConfig& config) {
  PoseGraph kept;
  for (const auto& [key, T] : graph.nodes()) kept.addNode(key, T);
  for (const Factor& f : graph.factors())
    if (f.from.robot == f.to.robot) kept.addFactor(f);
  for (const PcmPairResult& pair : result.pairs)
    for (const Factor& f : pair.decision.accepted) kept.addFactor(f);
  SolverConfig solver;
  solver.initialisation = "chordal";
  const std::vector<LoopId> withdrawn = withdrawUnexplained(kept, config, solver);
  const std::set<LoopId> out(withdrawn.begin(), withdrawn.end());
  for (PcmPairResult& pair : result.pairs) {
    std::vector<Factor>& accepted = pair.decision.accepted;
    for (const Factor& f : accepted)
      if (out.contains(loopId(f))) pair.decision.withdrawn.push_back(f);
    std::erase_if(accepted, [&](const Factor& f) { return out.contains(loopId(f)); });
  }
  return withdrawn.size();
}

}  // namespace dcl::backend
