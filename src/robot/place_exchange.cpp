// Descriptors and candidates between robots: a neighbour's descriptor
// received (stage 1) grows its chain and is searched in the own index; a
// match goes back as a candidate with the own keyframe's compact cloud
// (stage 2).

#include <algorithm>
#include <memory>
#include <utility>

#include <dcl/core/error.hpp>
#include <dcl/place/descriptor_codec.hpp>
#include <dcl/registration/cloud_codec.hpp>

#include "robot_node_impl.hpp"

namespace dcl::robot {
using detail::odometryFactor;

Neighbour& RobotNode::Impl::neighbour(core::RobotId robot) {
  auto it = neighbours.find(robot);
  if (it != neighbours.end()) return it->second;
  const core::RobotId a = std::min(self, robot);
  const core::RobotId b = a == self ? robot : self;
  it = neighbours.emplace(robot, Neighbour(backend::PairwiseConsistency(a, b, config.pcm))).first;
  addOwnChain(it->second.pcm);
  return it->second;
}

/// The odometry factors of the own keyframes so far (for a new PCM pair).
void RobotNode::Impl::addOwnChain(backend::PairwiseConsistency& pcm) const {
  for (const backend::Factor& step : own_chain) pcm.addRobotFactor(step);
}

/// Stage 1 received: the neighbour's chain grows; the own index is searched.
void RobotNode::Impl::onDescriptor(core::RobotId from, const comm::DescriptorMessage& d) {
  count("descriptors_received");
  Neighbour& n = neighbour(from);
  if (d.odometry) {
    n.pcm.addRobotFactor(odometryFactor(from, d.keyframe, *d.odometry));
    redecideIfRejecting(n);
  }
  std::shared_ptr<const place::IrisDescriptor> theirs;
  try {
    theirs = std::make_shared<const place::IrisDescriptor>(place::decodeIris(d.descriptor, iris));
  } catch (const core::Error&) {
    count("descriptors_undecodable");
    return;
  }
  for (const comm::Resemblance& r : d.resembles) judgeTheirRepeat(from, n, r, *theirs);
  const place::DistinctMatch found = index.queryDistinct(*theirs, ownPosition(), d.look_alike);
  if (found.refused) count("candidates_ambiguous");
  const std::optional<place::PlaceCandidate>& best = found.best;
  if (!best) return;
  const core::KeyframeId own = best->keyframe.keyframe;
  // The own place repeats elsewhere on the own route about as closely as the
  // match: in repeated structure the best of the repeats is chance (which of
  // them the keyframes happened to fall on at the same point of the block),
  // not the place.
  if (!config.index.beats(best->match.distance, own_alike.at(own.value())))
    return count("candidates_ambiguous");
  if (n.asked.contains({own, d.keyframe})) return;
  // Loops a few metres apart add little but their clouds and separators,
  // once the pair holds loops enough to be kept. Until then every match
  // is asked: robots that meet once, briefly, have only the few agreeing
  // loops of that one place to merge their maps on.
  const bool established = n.accepted.size() >= config.pcm.min_loops;
  if (established && askedNearby(n, own, d.keyframe)) return count("candidates_skipped_nearby");
  n.asked.emplace(std::pair{own, d.keyframe}, static_cast<float>(best->match.distance));
  n.asked_descriptors.emplace(d.keyframe, theirs);
  sendCandidate(from, own, d.keyframe, best->match);
}

/// Whether a candidate was sent for a pair of places a few keyframes from
/// (own, theirs) on both routes: the same two places. One that ties the own
/// place to another place of the neighbour's (a repeat of it, or the true
/// place where the first was an alias) is not nearby: PCM needs both to
/// choose between them.
bool RobotNode::Impl::askedNearby(const Neighbour& n, core::KeyframeId own,
                                  core::KeyframeId theirs) const {
  const std::uint64_t spacing = config.candidate_spacing;
  const std::uint64_t from = own.value() >= spacing ? own.value() - spacing + 1 : 0;
  for (auto it = n.asked.lower_bound({core::KeyframeId(from), core::KeyframeId(0)});
       it != n.asked.end() && it->first.first.value() < own.value() + spacing; ++it) {
    const std::uint64_t other = it->first.second.value();
    const std::uint64_t gap =
        other > theirs.value() ? other - theirs.value() : theirs.value() - other;
    if (gap < 2 * spacing) return true;
  }
  return false;
}

/// Stage 2: the own keyframe's compact cloud to the robot owning the place.
void RobotNode::Impl::sendCandidate(core::RobotId to, core::KeyframeId own, core::KeyframeId theirs,
                                    const place::Match& match) {
  registration::CloudCodecConfig codec;
  codec.voxel_size = config.verification.voxel_size;
  const core::Keyframe& k = mapper.keyframes().at(own.value());
  // match.yaw_rad is the yaw of T_theirs_own: the one the verifier starts from.
  comm::LoopCandidate c{own, theirs, static_cast<float>(match.yaw_rad),
                        static_cast<float>(match.distance),
                        registration::encodeVerificationCloud(k.cloud, codec)};
  messenger.send(to, std::move(c), now);
  count("candidates_sent");
}

}  // namespace dcl::robot
