// The distributed refinement within a round, after DGS: block steps,
// separators sent as increments, cost shares and the group's decisions, and
// a refinement ended before its schedule did.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <optional>
#include <set>
#include <utility>
#include <variant>

#include <spdlog/spdlog.h>

#include <dcl/comm/messages.hpp>
#include <dcl/robot/dgs_wire.hpp>

#include "robot_node_impl.hpp"

namespace dcl::robot {
namespace {

/// s a robot waiting in the refinement lets pass before sending its messages
/// of the step again (one may have been lost).
constexpr double kRefineResend = 0.04;
/// Finished rounds whose final refinement share is kept for members that lost it.
constexpr std::size_t kFinalSharesKept = 8;
/// A robot stopped while its round refines keeps the last kept step when the
/// cost fell by at most this share over the last kSettlingSteps kept steps.
constexpr double kSettlingDecrease = 0.02;
constexpr std::size_t kSettlingSteps = 10;

}  // namespace

using detail::Refinement;

/// The refinement's block: the round's factors, and own poses at DGS's
/// estimates, or, in a warm round, where the last round left them (when in
/// the round's frame; DGS's estimates are in it too). The neighbours'
/// separators come with their first messages.
///
/// A round whose refinement used all its steps is followed by a warm one
/// with the same loops: DGS solves a relaxation from scratch (its estimate
/// costs about twice the optimum's), and starting over from it would throw
/// away what the last round's steps gained. Rounds with new loops start
/// from DGS: its global linear solve takes in a large new correction
/// sooner than block steps from the old estimate do.
void RobotNode::Impl::startRefinement() {
  const bool warm = round->origin.warm && frame && round->origin.frame == frame;
  count(warm ? "refine_warm_starts" : "refine_cold_starts");
  backend::PoseGraph local;
  if (warm) {
    for (const auto& [key, T] : round->graph.nodes())
      if (key.robot == self) local.addNode(key, T);
  } else {
    for (const auto& [key, T] : round->agent.estimates())
      if (key.robot == self) local.addNode(key, T);
  }
  bool holds = false;  // loops to absent robots (roundGraph): they anchor the gauge
  for (const auto& [key, T] : round->graph.nodes()) {
    if (key.robot == self || !round->graph.isFixed(key)) continue;
    local.addNode(key, T);
    local.fix(key);
    holds = true;
  }
  for (const backend::Factor& f : round->graph.factors()) local.addFactor(f);
  if (self == *round->group.begin() && !holds && local.size() > 0)
    local.fix(local.nodes().begin()->first);
  round->refine.emplace(Refinement{backend::RefineAgent(self, local, config.refine),
                                   std::nullopt,
                                   0,
                                   true,
                                   false,
                                   {},
                                   {},
                                   {},
                                   now,
                                   {}});
  sendValues();
}

void RobotNode::Impl::onRefine(const RefineMessage& m) {
  if (finished.contains(m.round)) {
    if (abandoned.contains(m.round)) return tellAbandoned(m.from, m.round);
    return answerLateMember(m);
  }
  if (!round || m.round != round->number || !round->group.contains(m.from)) {
    if (!m.to) return;  // a share broadcast in a round this robot is not in
    spdlog::debug(
        "robot {}: t {:.2f}: ignores refinement step {} of round {} from {} (in round {})",
        core::robotName(self), now, m.step, m.round, core::robotName(m.from),
        round ? round->number : 0U);
    return count("refine_ignored");
  }
  if (!round->refine) tellDgsMemberLeft(m.from);
  // Buffered by step: a neighbour may be a step ahead, or DGS still running here.
  if (m.cost_share) {
    if (std::isfinite(*m.cost_share)) round->shares[m.step][m.from] = *m.cost_share;
    return;
  }
  auto& [step, values] = round->decoded[m.from];
  if (!values.empty() && m.step <= step) return;  // a copy of values already taken in
  if (!m.increments) {
    values = m.poses;
  } else {
    // Increments apply to the sender's previous step, which the sender only
    // sends on from once this robot has shared the step it was for.
    if (values.empty() || m.step != step + 1) return count("refine_increments_without_base");
    for (const auto& [key, D] : m.poses) {
      const auto base = values.find(key);
      if (base == values.end()) return count("refine_increments_without_base");
      base->second = base->second * D;
    }
  }
  step = m.step;
  round->values[m.step][m.from] = values;
}

/// A member still at the step at which this robot's refinement of a finished
/// round ended lost this robot's share of it: it gets the share again.
void RobotNode::Impl::answerLateMember(const RefineMessage& m) {
  if (m.finished) return;  // an answer: two robots done with the round would answer forever
  const auto it = final_shares.find(m.round);
  if (it == final_shares.end() || m.step != it->second.step) return;
  RefineMessage reply = it->second;
  reply.to = m.from;
  reply.finished = true;
  messenger.send(reply.to, toWire(reply), now);
  count("refine_final_shares_resent");
}

/// A member refining has left DGS: its last DGS message, which says so,
/// may have been lost. The agent is told as that message would have told it.
void RobotNode::Impl::tellDgsMemberLeft(core::RobotId member) {
  auto& [step, left] = round->heard[member];
  if (left || round->agent.stage() != backend::DgsStage::pose) return;
  left = true;
  backend::DgsMessage m;
  m.from = member;
  m.to = self;
  m.stage = backend::DgsStage::pose;
  m.round = round->number;
  m.iteration = ++step;
  m.initialised = true;
  m.converged = true;
  m.progress[member] = {step, step, true};
  round->agent.receive(m);
}

void RobotNode::Impl::send(RefineMessage m) {
  Refinement& r = *round->refine;
  messenger.send(m.to, toWire(m), now);
  r.sent.push_back(std::move(m));
  r.last_sent = now;
}

/// This step's separators to every linked neighbour; in step 0, DGS's
/// estimates to every member (none for a member without a loop here).
/// After step 0 they go as increments from what the neighbour holds from
/// the step before, which it has: it shared that step only once it had
/// them. The neighbour's copy is tracked as it decodes it, so the
/// increments' rounding never adds up.
void RobotNode::Impl::sendValues() {
  Refinement& r = *round->refine;
  const std::map<core::RobotId, std::set<core::PoseKey>>& separators = r.agent.separators();
  for (const core::RobotId member : round->group) {
    if (member == self || (r.step > 0 && !r.linked.contains(member))) continue;
    RefineMessage m{self, member, round->number, r.step, {}, std::nullopt, false};
    if (const auto it = separators.find(member); it != separators.end()) {
      for (const core::PoseKey& key : it->second) m.poses.emplace(key, r.agent.estimates().at(key));
    }
    auto& [told_step, told] = r.told[member];
    // In full when the neighbour holds no base, or (no realistic step) one
    // moved further than an increment can say.
    const auto within = [&](const auto& p) {
      const auto base = told.find(p.first);
      return base != told.end() &&
             (base->second.translation() - p.second.translation()).cwiseAbs().maxCoeff() <
                 0.5 * comm::kMaxIncrement;
    };
    const bool incremental = r.step > 0 && told_step + 1 == r.step && !m.poses.empty() &&
                             std::all_of(m.poses.begin(), m.poses.end(), within);
    if (incremental) {
      for (auto& [key, T] : m.poses) T = told.at(key).inverse() * T;
      m.increments = true;
    }
    const auto delivered = std::get<comm::PoseEstimates>(comm::asDelivered(toWire(m)));
    for (const auto& [id, T] : delivered.poses) {
      Eigen::Isometry3d& held = told[{self, id}];
      held = incremental ? held * T : T;
    }
    told_step = r.step;
    send(std::move(m));
  }
}

/// Takes in the values of this step from `robots` that have arrived; true
/// when every one of them has.
bool RobotNode::Impl::takeValues(const std::set<core::RobotId>& robots) {
  Refinement& r = *round->refine;
  bool all = true;
  for (const core::RobotId n : robots) {
    if (r.applied.contains(n)) continue;
    const auto& step_values = round->values[r.step];
    const auto it = step_values.find(n);
    if (it == step_values.end()) {
      all = false;
      continue;
    }
    r.agent.receive(it->second);
    r.applied.insert(n);
  }
  return all;
}

/// Moves the refinement on as far as what arrived allows: the block step
/// once the lower neighbours' values are in, the cost share once all
/// neighbours' are, the group's decision once every member's share is.
void RobotNode::Impl::advanceRefinement() {
  while (round && round->refine) {
    Refinement& r = *round->refine;
    if (!r.stepped) {
      std::set<core::RobotId> lower;
      for (const core::RobotId n : r.linked)
        if (n < self) lower.insert(n);
      if (!takeValues(lower)) return resendWhenStalled();
      (void)r.agent.step();
      r.stepped = true;
      sendValues();
    }
    if (!r.shared) {
      if (r.step == 0) {
        std::set<core::RobotId> others = round->group;
        others.erase(self);
        if (!takeValues(others)) return resendWhenStalled();
        const std::set<core::RobotId> neighbours = r.agent.neighbours();
        for (const auto& [member, poses] : round->values[0])
          if (!poses.empty() && neighbours.contains(member)) r.linked.insert(member);
      } else if (!takeValues(r.linked)) {
        return resendWhenStalled();
      }
      const auto share = static_cast<float>(r.agent.ownedCost());
      round->shares[r.step][self] = share;
      send({self, std::nullopt, round->number, r.step, {}, share, false});
      r.shared = true;
    }
    const std::map<core::RobotId, float>& shares = round->shares[r.step];
    if (shares.size() < round->group.size()) return resendWhenStalled();
    double total = 0.0;
    for (const auto& [member, share] : shares) total += static_cast<double>(share);
    spdlog::debug("robot {}: t {:.2f}: round {} refinement step {}: cost {:.6g}",
                  core::robotName(self), now, round->number, r.step, total);
    if (!r.schedule) {
      r.schedule.emplace(config.refine, total);
      r.agent.endRound(true);  // the neighbours' DGS separators become the kept ones
    } else {
      r.agent.endRound(r.schedule->endRound(total));
    }
    if (r.schedule->done()) {
      final_shares[round->number] = {self, self, round->number, r.step, {}, shares.at(self), false};
      while (final_shares.size() > kFinalSharesKept) final_shares.erase(final_shares.begin());
      count("refine_steps", r.schedule->rounds());
      count("refine_restarts", r.schedule->restarts());
      if (r.schedule->rounds() > 0)
        counters["refine_cost_ratio_last"] = r.schedule->cost() / r.schedule->roundCosts().front();
      checkRoundLoops(r.agent.estimates(), r.agent.neighbourValues());
      return finishRound(r.agent.estimates(), !r.schedule->converged());
    }
    nextStep(r);
  }
}

void RobotNode::Impl::nextStep(Refinement& r) {
  round->values.erase(r.step);
  round->shares.erase(r.step);
  // Keep the share just sent: a member still waiting for it may have lost it.
  std::erase_if(r.sent, [&](const RefineMessage& m) { return !m.cost_share || m.step != r.step; });
  ++r.step;
  round->progressed = now;
  r.stepped = false;
  r.shared = false;
  r.applied.clear();
  r.agent.beginRound(r.schedule->momentum());
}

void RobotNode::Impl::resendWhenStalled() {
  Refinement& r = *round->refine;
  if (now - r.last_sent < kRefineResend) return;
  for (const RefineMessage& m : r.sent) messenger.send(m.to, toWire(m), now);
  r.last_sent = now;
  count("refine_resent", static_cast<double>(r.sent.size()));
}

/// Ends the round's refinement before its schedule did (a member gone
/// silent): DGS's estimate and every kept refinement step are consistent
/// in the group, so the last kept one is taken rather than nothing.
void RobotNode::Impl::endRefinementEarly(const char* why) {
  count(why);
  tellAbandoned(std::nullopt, round->number);
  round->refine->agent.endRound(false);  // a step the group has not judged is not kept
  finishRound(round->refine->agent.estimates());
}

/// The robot stops while its round refines: the last kept step is taken
/// when the refinement is settling (its cost fell by at most
/// kSettlingDecrease over the last kSettlingSteps kept steps, which every
/// member sees alike), as a round that ran long does. One still repairing
/// DGS's estimate (a DGS under heavy loss can leave a chi-square in the
/// millions, which the refinement then lowers by most of a per cent a
/// step) is left, and the robot keeps what it held.
void RobotNode::Impl::stopRefinement() {
  const std::optional<backend::RefineSchedule>& schedule = round->refine->schedule;
  const std::vector<double>* costs = schedule ? &schedule->roundCosts() : nullptr;
  const bool settling =
      costs != nullptr && costs->size() >= kSettlingSteps &&
      (*costs)[costs->size() - kSettlingSteps] - costs->back() <= kSettlingDecrease * costs->back();
  if (!settling) return leave("rounds_left_unsettled_at_stop");
  endRefinementEarly("rounds_ended_by_stop");
}

}  // namespace dcl::robot
