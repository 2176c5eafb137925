// The own estimates and the frame they are in: taken from a finished round,
// solved alone when own loops closed and no one is in range, forgotten when
// no loop to a neighbour is left, and read for every keyframe.

#include <algorithm>
#include <cstddef>

#include <spdlog/spdlog.h>

#include <dcl/backend/centralized_solver.hpp>
#include <dcl/core/error.hpp>

#include "robot_node_impl.hpp"

namespace dcl::robot {
using detail::PoseMap;

/// The latest estimate of own keyframe `k`: optimised, or carried from the
/// last optimised keyframe before it by the local graph's relative poses.
Eigen::Isometry3d RobotNode::Impl::estimate(core::KeyframeId k) const {
  const std::vector<Eigen::Isometry3d>& local = mapper.smoothedPoses();
  const Eigen::Isometry3d& T_local = local.at(k.value());
  auto it = optimised.upper_bound(k);
  if (it == optimised.begin()) return T_local;
  --it;
  return it->second * local.at(it->first.value()).inverse() * T_local;
}

/// The own keyframes at their latest estimates, with the own factors
/// (odometry and intra-robot loops).
backend::PoseGraph RobotNode::Impl::ownGraph() const {
  backend::PoseGraph g;
  for (const core::Keyframe& k : mapper.keyframes()) g.addNode({self, k.id}, estimate(k.id));
  for (const backend::Factor& f : mapper.graph().factors()) g.addFactor(f);
  return g;
}

void RobotNode::Impl::finishRound(const PoseMap& estimates, bool capped) {
  for (const auto& [key, T] : estimates)
    if (key.robot == self) optimised[key.keyframe] = T;
  if (!round->origin.frame || round->origin.frame != frame) {
    anchors.clear();
    anchored_loops.clear();
  }
  if (round->origin.frame && round->refine) {
    for (const auto& [key, T] : round->refine->agent.neighbourValues()) anchors[key] = T;
    for (const backend::Factor& f : round->graph.factors())
      if (f.from.robot != f.to.robot) anchored_loops.insert(backend::loopId(f));
  }
  solved_own_loops = round->own_loops;
  frame = round->origin.frame;
  last_round_capped = capped;
  finished.insert(round->number);
  round.reset();
  count("dgs_rounds");
  forgetFrameIfUnlinked();  // its loops were withdrawn while it ran
}

/// No loop to a neighbour is left (every one withdrawn) and no round is
/// running: nothing holds the own map in another robot's frame, or bent
/// towards a neighbour's, any more. The estimates go back to the own local
/// graph's, in the own frame, as if no round had placed them; a later loop
/// starts over from there.
void RobotNode::Impl::forgetFrameIfUnlinked() {
  if (round || !loopNeighbours().empty() || (frame == self && optimised.empty())) return;
  spdlog::debug("robot {}: t {:.1f}: no loop to a neighbour is left; back in its own frame",
                core::robotName(self), now);
  optimised.clear();
  anchors.clear();
  anchored_loops.clear();
  last_signature.clear();
  last_round_capped = false;
  frame = self;
  count("frames_forgotten");
}

// ---- alone ------------------------------------------------------------------

/// Own loops closed since the estimates were last solved, and no one in
/// range to optimise with: the own graph is solved with the inter-robot
/// loops of the rounds in the current frame, the neighbours' poses held
/// where those rounds left them (the refinement's block problem, solved to
/// convergence by the centralized solver). Inter-robot loops no round has held yet wait for one:
/// both robots would take each in full against the other's old poses, and together overshoot. A
/// robot that never shared a round has nothing to solve: its own loops are already in its local
/// graph's estimates.
void RobotNode::Impl::maybeSolveAlone() {
  if (!config.solve_alone || round || anchors.empty()) return;
  if (mapper.loops().size() == solved_own_loops) return;
  if (now - std::max(last_solved_alone, last_round_start) < config.optimise_period) return;
  if (group().size() > 1) return;  // the group's round takes the loops in
  last_solved_alone = now;
  solved_own_loops = mapper.loops().size();
  backend::PoseGraph g = ownGraph();
  const std::size_t held = addHeldLoops(g, {self});
  if (held == 0) return;
  backend::SolverConfig solver;
  solver.threads = 1;
  solver.fix_lowest = false;
  try {
    const backend::SolverSummary summary = backend::solveCentralized(g, solver);
    spdlog::debug(
        "robot {}: t {:.1f}: solved alone on {} loops to neighbours: cost {:.6g} -> {:.6g}",
        core::robotName(self), now, held, summary.initial_cost, summary.final_cost);
  } catch (const core::Error& e) {
    spdlog::warn("robot {}: solving alone failed: {}", core::robotName(self), e.what());
    return count("solved_alone_failed");
  }
  for (const auto& [key, T] : g.nodes())
    if (key.robot == self) optimised[key.keyframe] = T;
  count("solved_alone");
}

/// Adds to `g` the accepted inter-robot loops of the rounds in the current
/// frame to robots outside `members`, their other ends held (fixed) where
/// those rounds left them; returns how many.
std::size_t RobotNode::Impl::addHeldLoops(backend::PoseGraph& g,
                                          const std::set<core::RobotId>& members) const {
  std::size_t held = 0;
  for (const auto& [robot, n] : neighbours) {
    if (members.contains(robot)) continue;
    for (const auto& [id, f] : n.loops) {
      const core::PoseKey& other = f.from.robot == self ? f.to : f.from;
      const auto anchor = anchors.find(other);
      if (!n.accepted.contains(id) || !anchored_loops.contains(id) || anchor == anchors.end())
        continue;
      if (!g.hasNode(other)) {
        g.addNode(other, anchor->second);
        g.fix(other);
      }
      g.addFactor(f);
      ++held;
    }
  }
  return held;
}

}  // namespace dcl::robot
