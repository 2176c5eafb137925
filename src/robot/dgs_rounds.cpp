// Optimisation rounds (Algorithm 1): announcements and the groups they
// make, rounds started, joined and left, and the DGS steps taken in step
// with the group.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <set>
#include <variant>
#include <vector>

#include <spdlog/spdlog.h>

#include <dcl/robot/dgs_wire.hpp>

#include "robot_node_impl.hpp"

namespace dcl::robot {
namespace {

using comm::Body;

/// s a robot waiting for a member's DGS step lets pass before sending its own
/// last step's messages again (one may have been lost, and the member may be
/// waiting for it in turn).
constexpr double kDgsResend = 0.04;
/// s a robot waits for a member's DGS step before stepping without it: a few
/// re-sends, so a step is skipped only when its messages are lost again and again.
constexpr double kDgsPatience = 0.2;
/// DGS steps a robot takes in a round without solving its block (no own
/// anchor and no value of a neighbour's separator it holds) before it leaves
/// the round: the members hold different loops (a loop's measurement lost on
/// its way to one of them), share no separator, and would step to the cap.
constexpr int kUngroundedSteps = 20;

/// `body` (a DGS message) with every member of `group` in its progress (a
/// member not heard of yet as not started) and how the round starts. The
/// progress a DGS agent relays holds only the members it has heard from, and
/// a robot joining on a first message must learn the whole group from it.
Body withMembers(Body body, const std::set<core::RobotId>& group, const RoundOrigin& origin) {
  const auto add = [&](comm::DgsState& state) {
    state.frame = origin.frame;
    state.warm = origin.warm;
    for (const core::RobotId member : group) {
      const bool listed =
          std::any_of(state.progress.begin(), state.progress.end(),
                      [&](const comm::MemberProgress& p) { return p.robot == member; });
      if (!listed) state.progress.push_back({member, 0, -1, false});
    }
  };
  if (auto* s = std::get_if<comm::DgsState>(&body)) add(*s);
  if (auto* r = std::get_if<comm::RotationEstimates>(&body)) add(r->state);
  if (auto* p = std::get_if<comm::PoseEstimates>(&body)) add(p->state);
  return body;
}

std::uint8_t initiator(std::uint32_t round) {
  return static_cast<std::uint8_t>(round & 0xFFU);
}

}  // namespace

using detail::Link;
using detail::Round;

std::set<core::RobotId> RobotNode::Impl::loopNeighbours() const {
  std::set<core::RobotId> out;
  for (const auto& [robot, n] : neighbours)
    if (!n.accepted.empty()) out.insert(robot);
  return out;
}

/// The loops this robot's part of a round's graph holds: accepted inter-robot
/// loops and its own intra-robot loops, plus the loops it replaced by the
/// lower robot's measurement (addLoop). A round starts when any member's
/// count changed: an intra-robot loop closed after the last round moves
/// keyframes that round already placed, and only a round puts them back in
/// one frame; a replaced loop changes the factor a round used.
std::uint32_t RobotNode::Impl::loopsHeld() const {
  std::size_t accepted = mapper.loops().size() + loops_replaced;
  for (const auto& [robot, n] : neighbours) accepted += n.accepted.size();
  return static_cast<std::uint32_t>(accepted);
}

/// Tells everyone in range which robots this one shares loops with.
void RobotNode::Impl::announce() {
  if (now - last_announce < config.announce_period) return;
  last_announce = now;
  comm::DgsState state;
  state.stage = comm::OptimisationStage::idle;
  state.iteration = loopsHeld();
  for (const core::RobotId robot : loopNeighbours()) state.progress.push_back({robot});
  if (state.progress.empty()) return;
  messenger.send(std::nullopt, std::move(state), now);
}

void RobotNode::Impl::onAnnouncement(core::RobotId from, const comm::DgsState& state) {
  Link& link = links[from];
  link.neighbours.clear();
  for (const comm::MemberProgress& p : state.progress) link.neighbours.insert(p.robot);
  link.loops = state.iteration;
}

/// The robots in range joined to this one by loops, as announced.
std::set<core::RobotId> RobotNode::Impl::group() const {
  const std::set<core::RobotId> present = messenger.neighbours();
  std::set<core::RobotId> members{self};
  std::vector<core::RobotId> todo{self};
  while (!todo.empty()) {
    const core::RobotId r = todo.back();
    todo.pop_back();
    std::set<core::RobotId> next = r == self ? loopNeighbours() : std::set<core::RobotId>{};
    if (const auto it = links.find(r); it != links.end() && r != self) next = it->second.neighbours;
    for (const core::RobotId n : next) {
      if ((n == self || present.contains(n)) && members.insert(n).second) todo.push_back(n);
    }
  }
  return members;
}

/// True when the loops of `current` number half as many again as those of
/// the last round's signature (none: false).
bool RobotNode::Impl::grewByHalf(
    const std::vector<std::pair<core::RobotId, std::uint32_t>>& current) const {
  const auto total = [](const auto& signature) {
    std::uint64_t sum = 0;
    for (const auto& [robot, loops] : signature) sum += loops;
    return sum;
  };
  const std::uint64_t last = total(last_signature);
  return last > 0 && 2 * total(current) >= 3 * last;
}

std::vector<std::pair<core::RobotId, std::uint32_t>> RobotNode::Impl::signature(
    const std::set<core::RobotId>& members) const {
  std::vector<std::pair<core::RobotId, std::uint32_t>> out;
  for (const core::RobotId r : members) {
    const auto it = links.find(r);
    out.emplace_back(r, r == self ? loopsHeld() : (it == links.end() ? 0 : it->second.loops));
  }
  return out;
}

/// The lowest robot of a group starts a round when the group's loops
/// changed, an optimise_period after the last; an announce_period after it
/// when the loops the group holds grew by half since: a pair's first round
/// is made on the few loops PCM needs, and robots that meet briefly part
/// soon, so it is redone while they are still in range.
void RobotNode::Impl::maybeStartRound() {
  if (round || now - last_round_start < config.announce_period) return;
  const std::set<core::RobotId> members = group();
  if (members.size() < 2 || *members.begin() != self) return;
  const auto current = signature(members);
  if (now - last_round_start < config.optimise_period && !grewByHalf(current)) return;
  // Same loops: nothing to do, unless the last round ran out of steps.
  const bool again = current == last_signature;
  if (again && !(last_round_capped && frame)) return;
  join(((++rounds_started) << 8U) | self.value(), members, {frame, again});
}

/// The own part of the graph a round optimises: own poses at their latest
/// estimates, own factors, the accepted loops to the group's members, and,
/// in a round in the current frame, the loops to robots out of the group
/// held where the rounds in this frame left those robots (hold_absent):
/// what the round moves stays where they placed their maps, so the swarm's
/// maps still agree when they cannot hear of it. Held loops anchor the
/// round's gauge, in DGS and in the refinement, where the lowest member's
/// first pose would otherwise be pinned: the two would pull apart.
backend::PoseGraph RobotNode::Impl::roundGraph(const std::set<core::RobotId>& members,
                                               const RoundOrigin& origin) {
  backend::PoseGraph g = ownGraph();
  if (config.hold_absent && frame && origin.frame == frame) {
    if (const std::size_t held = addHeldLoops(g, members); held > 0)
      count("round_held_loops", static_cast<double>(held));
  }
  for (const auto& [robot, n] : neighbours) {
    if (!members.contains(robot)) continue;
    for (const auto& [id, f] : n.loops) {
      if (!n.accepted.contains(id)) continue;
      for (const core::PoseKey& end : {f.from, f.to})
        if (!g.hasNode(end)) g.addNode(end, Eigen::Isometry3d::Identity());
      g.addFactor(f);
    }
  }
  return g;
}

void RobotNode::Impl::join(std::uint32_t number, const std::set<core::RobotId>& members,
                           const RoundOrigin& origin) {
  if (round) leave("dgs_rounds_abandoned");
  backend::PoseGraph graph = roundGraph(members, origin);
  round.emplace(Round{number,
                      members,
                      origin,
                      backend::DgsAgent(self, graph, config.dgs),
                      now,
                      std::move(graph),
                      {},
                      now,
                      std::nullopt,
                      {},
                      {},
                      mapper.loops().size(),
                      {}});
  round->agent.startRound(members, number);
  last_signature = signature(members);
  last_round_start = now;
  spdlog::debug("robot {}: t {:.1f}: joins round {} of {} robots", core::robotName(self), now,
                number, members.size());
  count("dgs_rounds_joined");
  // A member that holds no loop to the others yet (the measurement of the
  // loop that made the initiator count it in is still on its way) could
  // neither anchor nor solve its block: the round would step to its cap.
  const std::set<core::RobotId> linked = round->agent.neighbours();
  if (std::none_of(members.begin(), members.end(),
                   [&](core::RobotId r) { return r != self && linked.contains(r); }))
    leave("dgs_rounds_left_without_loops", true);
}

/// Abandons the round; the group tries again when it is whole (its loops
/// unchanged or not). A round a member left before it could begin (its
/// loops not there yet) is tried again an announce_period on, not an
/// optimise_period.
void RobotNode::Impl::leave(const char* why, bool soon) {
  if (soon)
    last_round_start =
        std::min(last_round_start, now - config.optimise_period + config.announce_period);
  round->agent.abortRound();
  tellAbandoned(std::nullopt, round->number);
  finished.insert(round->number);
  round.reset();
  last_signature.clear();
  last_round_capped = false;
  count(why);
  spdlog::debug("robot {}: t {:.1f}: leaves its round ({})", core::robotName(self), now, why);
  forgetFrameIfUnlinked();
}

void RobotNode::Impl::onDgs(const backend::DgsMessage& m, const RoundOrigin& origin) {
  if (finished.contains(m.round)) return tellAbandoned(m.from, m.round);
  if (!round || m.round != round->number) {
    // A round led by a lower robot wins over this robot's own.
    if (round && initiator(m.round) >= initiator(round->number)) return count("dgs_ignored");
    // Every DGS message names the whole group (withMembers), so each member
    // holds the initiator's group, whatever its own view of the announcements:
    // the refinement's shares add up only over the same members.
    std::set<core::RobotId> members{m.from};
    for (const auto& [robot, p] : m.progress) members.insert(robot);
    if (!members.contains(self)) return count("dgs_ignored");
    join(m.round, members, origin);
    if (!round) return;
  }
  auto& [step, left] = round->heard[m.from];
  step = std::max(step, m.iteration);
  if (const auto it = m.progress.find(m.from); it != m.progress.end())
    left = left || (m.stage == backend::DgsStage::pose && it->second.finished);
  round->agent.receive(m);
  for (const backend::DgsMessage& reply : round->agent.replies()) {
    sendDgs(reply);
    count("dgs_stragglers_answered");
  }
}

void RobotNode::Impl::sendDgs(const backend::DgsMessage& m) {
  messenger.send(m.to, withMembers(toWire(m), round->group, round->origin), now);
}

/// One DGS step a tick, then the refinement; the estimates taken when the round is done.
void RobotNode::Impl::stepRound() {
  if (!round) return;
  const std::set<core::RobotId> present = messenger.neighbours();
  const bool whole = std::all_of(round->group.begin(), round->group.end(),
                                 [&](core::RobotId r) { return r == self || present.contains(r); });
  const bool late = now - round->progressed > config.round_timeout;
  if (round->refine && (!whole || late))
    return endRefinementEarly(whole ? "refine_timeouts" : "refine_cut_short");
  if (!whole || late) return leave("dgs_rounds_abandoned");
  if (!round->refine) {
    if (!membersInStep()) return;
    round->agent.iterate();
    round->progressed = now;
    if (!round->agent.initialised() && round->agent.iteration() >= kUngroundedSteps)
      return leave("dgs_rounds_left_ungrounded", true);
    for (const backend::DgsMessage& m : round->agent.outgoing()) sendDgs(m);
    round->dgs_last_sent = now;
    if (round->agent.stage() != backend::DgsStage::done) return;
    const int rotation = round->agent.stageIterations(backend::DgsStage::rotation);
    const int pose = round->agent.stageIterations(backend::DgsStage::pose);
    spdlog::debug("robot {}: t {:.2f}: round {} DGS done: {} + {} steps", core::robotName(self),
                  now, round->number, rotation, pose);
    count("dgs_iterations_rotation", rotation);
    count("dgs_iterations_pose", pose);
    // A stage that ran to its cap did not converge: its estimate may be far off.
    if (rotation >= config.dgs.max_rotation_iterations) count("dgs_rotation_stages_capped");
    if (pose >= config.dgs.max_pose_iterations) count("dgs_pose_stages_capped");
    if (config.refine.max_rounds == 0) return finishRound(round->agent.estimates());
    startRefinement();
  }
  advanceRefinement();
}

/// Steps in Algorithm 1's order, in step with the group: a robot takes its
/// k-th DGS step once every lower member it has heard from in the round has
/// sent its k-th and every higher one its (k-1)-th (or has left DGS), as the
/// robots of an offline run step in turn. Members stepping at their own
/// pace never see a step at which the whole group was converged (the
/// members' step counts drift apart), and stepping all at once on each
/// other's previous values is Jacobi, which oscillates when three or more
/// robots are tightly looped. A robot waiting sends its last step again
/// every kDgsResend: a message lost either way leaves both robots waiting,
/// each for the other. A member silent for kDgsPatience is not waited for
/// longer.
bool RobotNode::Impl::membersInStep() {
  const int next = round->agent.iteration() + 1;
  for (const auto& [robot, heard] : round->heard) {
    const int needed = robot < self ? next : next - 1;
    if (heard.second || heard.first >= needed) continue;
    if (now - round->waiting_since < kDgsPatience) {
      resendDgsStep();
      return false;
    }
    count("dgs_waits_cut_short");
    spdlog::debug(
        "robot {}: t {:.2f}: round {} step {} stage {} stops waiting for {} (heard step {})",
        core::robotName(self), now, round->number, next, static_cast<int>(round->agent.stage()),
        core::robotName(robot), heard.first);
    break;
  }
  round->waiting_since = now;
  return true;
}

void RobotNode::Impl::resendDgsStep() {
  const std::vector<backend::DgsMessage> last = round->agent.outgoing();
  if (last.empty() || now - round->dgs_last_sent < kDgsResend) return;
  for (const backend::DgsMessage& m : last) sendDgs(m);
  round->dgs_last_sent = now;
  count("dgs_resent", static_cast<double>(last.size()));
}

/// Tells `to` (everyone in range: none) that this robot left round `number`
/// before it was done: the round cannot be finished without it (its
/// refinement adds up every member's share), and a member still in it
/// would wait for its steps until the round timed out. Nothing for a
/// round this robot finished.
void RobotNode::Impl::tellAbandoned(std::optional<core::RobotId> to, std::uint32_t number) {
  if (to && !abandoned.contains(number)) return;
  abandoned.insert(number);
  comm::DgsState notice;
  notice.round = number;
  notice.stage = comm::OptimisationStage::done;
  notice.abort = true;
  messenger.send(to, notice, now);
  if (to) count("abandoned_rounds_told");
}

/// A member left the round: this robot leaves it too (in DGS) or keeps its
/// refinement's last kept step, as when the member goes silent. A round not
/// joined yet is not joined.
void RobotNode::Impl::onAbort(core::RobotId from, std::uint32_t number) {
  if (!round || round->number != number) {
    finished.insert(number);
    return;
  }
  if (!round->group.contains(from)) return;
  if (round->refine) return endRefinementEarly("refine_ended_by_member");
  leave("dgs_rounds_left_by_member", true);
}

}  // namespace dcl::robot
