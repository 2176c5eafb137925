// Which loops a robot pair keeps: every verified loop goes to the pair's
// PCM; loops are withdrawn again at places a robot passes twice, and when
// both robots of a pair see that a round's solution cannot explain them.

#include <algorithm>
#include <cstddef>
#include <optional>
#include <vector>

#include <spdlog/spdlog.h>

#include <dcl/backend/loop_check.hpp>

#include "robot_node_impl.hpp"

namespace dcl::robot {
using detail::pairLoop;
using detail::PoseMap;

/// A loop the verifier `f.from.robot` measured. Two robots that sent each
/// other a candidate for the same two keyframes each verify it: both then
/// keep the lower robot's measurement, whichever arrived first, so that the
/// two hold, check and optimise the same factor. (Each keeping the one that
/// came last, each other's, they pulled a round's refinement against each
/// other: campus-9 seed 3 ended at 2.5 times the optimum's chi-square.)
void RobotNode::Impl::addLoop(core::RobotId other, const backend::Factor& f) {
  Neighbour& n = neighbour(other);
  const backend::LoopId id = backend::loopId(f);
  const auto held = n.loops.find(id);
  if (held == n.loops.end()) {
    n.loops.emplace(id, f);
    (void)n.pcm.addLoop(f);
  } else if (f.from.robot < held->second.from.robot) {
    held->second = f;
    (void)n.pcm.replaceLoop(f);
    ++loops_replaced;
    count("inter_loops_replaced");
  } else {
    return count("inter_loops_measured_twice");
  }
  decide(n);
}

void RobotNode::Impl::decide(Neighbour& n) {
  const backend::PcmDecision& decision = n.pcm.decide();
  n.accepted.clear();
  for (const backend::Factor& a : decision.accepted) n.accepted.insert(backend::loopId(a));
  recountPcm();
}

/// A chain grew: loops PCM could not yet relate (the steps between them had
/// not all arrived) are judged again, so both robots of the pair end with the
/// same decision whatever order loops and descriptors came in.
void RobotNode::Impl::redecideIfRejecting(Neighbour& n) {
  if (n.accepted.size() < n.loops.size()) decide(n);
}

void RobotNode::Impl::recountPcm() {
  double accepted = 0.0;
  double known = 0.0;
  for (const auto& [robot, n] : neighbours) {
    accepted += static_cast<double>(n.accepted.size());
    known += static_cast<double>(n.loops.size());
  }
  counters["inter_loops"] = known;
  counters["inter_loops_accepted"] = accepted;
  counters["inter_loops_rejected"] = known - accepted;
}

// ---- loops at repeated places -------------------------------------------
//
// A loop is made by the robot that arrives second at a place (it searches
// the first robot's descriptor, or the first its own index), and its
// distinctness test only knows both routes so far. Either robot may pass a
// place like it later: the robot that asked (it holds both descriptors)
// then tests the match again as a search over the whole route would have,
// and withdraws a loop whose match does not clearly beat the repeat, and
// tells the other robot, which withdraws it too.

/// The own new keyframe `later` resembles own keyframe `earlier`, far from it
/// on the route: the loops to `robot` asked at `earlier` are judged again,
/// against the closer of `later` to the neighbour's place and of `later` to
/// `earlier` (a place that repeats on the own route is no place to tie two
/// robots at, however the neighbour's scan fell).
void RobotNode::Impl::judgeOwnRepeat(core::RobotId robot, Neighbour& n,
                                     const comm::Resemblance& earlier,
                                     const place::PlaceDescriptor& later) {
  for (auto it = n.asked.lower_bound({earlier.keyframe, core::KeyframeId(0)});
       it != n.asked.end() && it->first.first == earlier.keyframe; ++it) {
    const auto theirs = n.asked_descriptors.find(it->first.second);
    if (theirs == n.asked_descriptors.end()) continue;
    const double repeat = std::min(descriptor->match(*theirs->second, later).distance,
                                   static_cast<double>(earlier.distance));
    judgeRepeat(robot, n, it->first, it->second, repeat);
  }
}

/// Neighbour `robot`'s new keyframe (described by `later`) resembles its
/// keyframe `earlier`, far from it on its route: the loops asked at
/// `earlier` are judged again, as judgeOwnRepeat does.
void RobotNode::Impl::judgeTheirRepeat(core::RobotId robot, Neighbour& n,
                                       const comm::Resemblance& earlier,
                                       const place::PlaceDescriptor& later) {
  for (const auto& [pair, distance] : n.asked) {
    if (pair.second != earlier.keyframe) continue;
    const place::PlaceDescriptor& own = index.description(pair.first.value());
    const double repeat =
        std::min(descriptor->match(later, own).distance, static_cast<double>(earlier.distance));
    judgeRepeat(robot, n, pair, distance, repeat);
  }
}

/// Withdraws the loop asked as `pair` (own, theirs) with match distance
/// `distance` when a repeat of either place is within
/// PlaceIndexConfig::distinct_ratio of it (`repeat`, a descriptor distance),
/// and tells `robot`.
void RobotNode::Impl::judgeRepeat(core::RobotId robot, Neighbour& n,
                                  const std::pair<core::KeyframeId, core::KeyframeId>& pair,
                                  double distance, double repeat) {
  if (config.index.beats(distance, repeat)) {
    spdlog::trace("robot {}: t {:.1f}: keeps the loop {}{} - {}{}: match {:.3f}, a repeat {:.3f}",
                  core::robotName(self), now, core::robotName(self), pair.first.value(),
                  core::robotName(robot), pair.second.value(), distance, repeat);
    return;
  }
  const core::PoseKey own{self, pair.first};
  const core::PoseKey theirs{robot, pair.second};
  if (!n.pcm.withdraw(pairLoop(own, theirs))) return;
  comm::LoopMeasurement notice{pair.second, pair.first, comm::LoopStatus::repeated};
  messenger.send(robot, notice, now);
  count("inter_loops_withdrawn_repeated");
  spdlog::debug("robot {}: t {:.1f}: withdraws the loop {}{} - {}{}: match {:.3f}, a repeat {:.3f}",
                core::robotName(self), now, core::robotName(self), pair.first.value(),
                core::robotName(robot), pair.second.value(), distance, repeat);
  decide(n);
  forgetFrameIfUnlinked();
}

/// A notice from `from`: it withdrew loop (m.match of theirs, m.query of
/// this robot's), a repeated place's.
void RobotNode::Impl::onRepeated(core::RobotId from, const comm::LoopMeasurement& m) {
  count("repeated_notices_received");
  Neighbour& n = neighbour(from);
  const core::PoseKey theirs{from, m.match};
  const core::PoseKey mine{self, m.query};
  if (!n.pcm.withdraw(pairLoop(mine, theirs))) return;
  count("inter_loops_withdrawn_repeated");
  decide(n);
  forgetFrameIfUnlinked();
}

// ---- the second line of defence -----------------------------------------

/// After a round whose refinement ran its course (every member reaches
/// that end alike), the loops to its members its solution cannot explain
/// (backend/loop_check.hpp), at the own final poses and the members'
/// separators as they were last sent. Of the robot pair this robot sees
/// explained worst, when it is one of the two, the loops beyond the
/// threshold go to the partner as notices for this round. A pair's loops
/// are withdrawn when both of its robots saw it as their worst in the same
/// round (withdrawIfBothSaw). The round's solution weighs the odometry as
/// its covariance says, so a wrong cluster that long odometry chains can
/// bend to hides from this check; it catches the clusters that leave their
/// error on the loops (a robot's chain too short or too stiff to bend).
/// The stronger check, which holds the chains stiff and needs the whole
/// group's graph, runs offline (`pcm --check-loops`, `bench loops`).
void RobotNode::Impl::checkRoundLoops(const PoseMap& own, const PoseMap& members) {
  if (!config.loop_check.enabled) return;
  std::vector<backend::Factor> loops;
  for (const backend::Factor& f : round->graph.factors()) {
    const core::RobotId other = f.from.robot == self ? f.to.robot : f.from.robot;
    if (f.from.robot != f.to.robot && round->group.contains(other)) loops.push_back(f);
  }
  const auto lookup = [&](const core::PoseKey& key) -> std::optional<Eigen::Isometry3d> {
    const PoseMap& in = key.robot == self ? own : members;
    const auto it = in.find(key);
    return it == in.end() ? std::nullopt : std::optional(it->second);
  };
  const std::optional<backend::Unexplained> worst =
      backend::worstUnexplained(backend::loopResiduals(loops, lookup), config.loop_check);
  if (!worst) return;
  const auto [a, b] = worst->robots;
  if (a != self && b != self) return;
  const core::RobotId partner = a == self ? b : a;
  for (const backend::LoopId& id : worst->loops) {
    const bool mine_first = id.first.robot == self;
    comm::LoopMeasurement notice{mine_first ? id.second.keyframe : id.first.keyframe,
                                 mine_first ? id.first.keyframe : id.second.keyframe,
                                 comm::LoopStatus::unexplained};
    notice.round = round->number;
    messenger.send(partner, notice, now);
  }
  count("inter_loops_unexplained", static_cast<double>(worst->loops.size()));
  Neighbour& n = neighbour(partner);
  n.own_unexplained[round->number] = {worst->loops.begin(), worst->loops.end()};
  withdrawIfBothSaw(partner, n, round->number);
}

/// A notice from `from`: the solution of `m.round` does not explain loop
/// (m.match of theirs, m.query of this robot's).
void RobotNode::Impl::onUnexplained(core::RobotId from, const comm::LoopMeasurement& m) {
  count("unexplained_notices_received");
  Neighbour& n = neighbour(from);
  const core::PoseKey theirs{from, m.match};
  const core::PoseKey mine{self, m.query};
  n.their_unexplained[m.round].insert(pairLoop(mine, theirs));
  withdrawIfBothSaw(from, n, m.round);
}

/// Withdraws the loops both this robot and `partner` gave notice of for
/// `round`, and those either did once both did (so both withdraw the same
/// union); forgets notices of rounds long past.
void RobotNode::Impl::withdrawIfBothSaw(core::RobotId partner, Neighbour& n,
                                        std::uint32_t round_number) {
  const auto own = n.own_unexplained.find(round_number);
  const auto theirs = n.their_unexplained.find(round_number);
  if (own != n.own_unexplained.end() && theirs != n.their_unexplained.end()) {
    std::size_t withdrawn = 0;
    for (const auto* ids : {&own->second, &theirs->second})
      for (const backend::LoopId& id : *ids) withdrawn += n.pcm.withdraw(id) ? 1 : 0;
    if (withdrawn > 0) {
      count("inter_loops_withdrawn", static_cast<double>(withdrawn));
      spdlog::debug("robot {}: t {:.1f}: withdraws {} loops to {} (round {})",
                    core::robotName(self), now, withdrawn, core::robotName(partner), round_number);
      decide(n);
      forgetFrameIfUnlinked();
    }
  }
  constexpr std::size_t kRoundsKept = 8;
  while (n.own_unexplained.size() > kRoundsKept) n.own_unexplained.erase(n.own_unexplained.begin());
  while (n.their_unexplained.size() > kRoundsKept)
    n.their_unexplained.erase(n.their_unexplained.begin());
}

}  // namespace dcl::robot
