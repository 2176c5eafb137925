// The robot node's construction, the dispatch of a tick's messages to their
// stages, and the public methods. The stages are in the files named in
// robot_node_impl.hpp.

#include <cmath>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <variant>

#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>
#include <dcl/place/descriptor.hpp>
#include <dcl/robot/dgs_wire.hpp>
#include <dcl/robot/robot_node.hpp>

#include "robot_node_impl.hpp"

namespace dcl::robot {
namespace {

using comm::Message;

}  // namespace

void validate(const RobotConfig& config) {
  if (config.descriptor.kind != "iris")
    throw core::Error("robot config: descriptor.kind '" + config.descriptor.kind +
                      "': robots exchange LiDAR-Iris descriptors only (the wire codec's)");
  core::checkConfig(config.odometry, "robot config: odometry");
  core::checkConfig(config.mapper, "robot config: mapper");
  core::checkConfig(config.descriptor, "robot config: descriptor");
  core::checkConfig(config.index, "robot config: index");
  core::checkConfig(config.verification, "robot config: verification");
  core::checkConfig(config.pcm, "robot config: pcm");
  core::checkConfig(config.loop_check, "robot config: loop_check");
  core::checkConfig(config.messenger, "robot config: messenger");
  core::checkConfig(config.dgs, "robot config: dgs");
  core::checkConfig(config.refine, "robot config: refine");
  if (config.candidate_spacing < 1)
    throw core::Error("robot config: candidate_spacing must be at least 1");
  for (const auto& [name, value] :
       {std::pair{"loop_sigma_translation", config.loop_sigma_translation},
        std::pair{"loop_sigma_rotation", config.loop_sigma_rotation},
        std::pair{"loop_sigma_tilt", config.loop_sigma_tilt}}) {
    if (!(value >= 0.0) || !std::isfinite(value))
      throw core::Error(std::string("robot config: ") + name + " must be a finite number >= 0");
  }
  for (const auto& [name, value] : {std::pair{"optimise_period", config.optimise_period},
                                    std::pair{"round_timeout", config.round_timeout},
                                    std::pair{"announce_period", config.announce_period}}) {
    if (!(value > 0.0) || !std::isfinite(value))
      throw core::Error(std::string("robot config: ") + name + " must be a finite number > 0");
  }
}

RobotNode::Impl::Impl(comm::Transport& transport, const RobotConfig& c, std::uint32_t incarnation,
                      std::unique_ptr<odometry::Odometry> front_end)
    : self(transport.self()),
      config(c),
      messenger(transport, incarnation, c.messenger),
      odometry(front_end ? std::move(front_end)
                         : std::make_unique<odometry::LidarOdometry>(c.odometry)),
      mapper(transport.self(), c.mapper),
      iris(c.descriptor.iris),
      descriptor(place::makeDescriptor(c.descriptor)),
      index(descriptor, transport.self(), c.index),
      frame(transport.self()) {
  validate(config);
  config.pcm.intra_loops = false;
}

void RobotNode::Impl::tick(double time) {
  now = time;
  for (const Message& m : messenger.poll(now)) handle(m);
  announce();
  maybeStartRound();
  stepRound();
  maybeSolveAlone();
}

void RobotNode::Impl::handle(const Message& m) {
  const core::RobotId from = m.header.sender;
  if (const auto* h = std::get_if<comm::Heartbeat>(&m.body)) {
    const auto [it, first] = announced_keyframes.try_emplace(from, h->keyframes);
    if (!first && h->keyframes > it->second) peers_mapped_at = now;
    it->second = h->keyframes;  // a restarted robot counts from 0 again
    return;
  }
  if (const auto* d = std::get_if<comm::DescriptorMessage>(&m.body)) return onDescriptor(from, *d);
  if (const auto* c = std::get_if<comm::LoopCandidate>(&m.body)) return onCandidate(from, *c);
  if (const auto* l = std::get_if<comm::LoopMeasurement>(&m.body)) return onMeasurement(from, *l);
  if (const auto* a = std::get_if<comm::DgsState>(&m.body);
      a != nullptr && a->stage == comm::OptimisationStage::idle)
    return onAnnouncement(from, *a);
  if (const auto* a = std::get_if<comm::DgsState>(&m.body); a != nullptr && a->abort)
    return onAbort(from, a->round);
  if (std::optional<RefineMessage> r = refineFromWire(m)) return onRefine(*r);
  if (std::optional<backend::DgsMessage> dgs = fromWire(m)) onDgs(*dgs, roundOrigin(m));
}

RobotNode::RobotNode(comm::Transport& transport, const RobotConfig& config,
                     std::uint32_t incarnation)
    : RobotNode(transport, config, incarnation, nullptr) {}
RobotNode::RobotNode(comm::Transport& transport, const RobotConfig& config,
                     std::uint32_t incarnation, std::unique_ptr<odometry::Odometry> front_end)
    : impl_(std::make_unique<Impl>(transport, config, incarnation, std::move(front_end))) {}
RobotNode::~RobotNode() = default;

core::RobotId RobotNode::id() const {
  return impl_->self;
}

void RobotNode::addScan(double stamp, const core::PointCloud& scan,
                        const std::optional<Eigen::Vector3d>& up) {
  impl_->addScan(stamp, scan, up);
}

void RobotNode::tick(double now) {
  impl_->tick(now);
}

const std::vector<core::Keyframe>& RobotNode::keyframes() const {
  return impl_->mapper.keyframes();
}

const backend::PoseGraph& RobotNode::localGraph() const {
  return impl_->mapper.graph();
}

std::vector<InterLoop> RobotNode::interLoops() const {
  std::vector<InterLoop> out;
  for (const auto& [robot, n] : impl_->neighbours) {
    for (const auto& [id, f] : n.loops) out.push_back({f, n.accepted.contains(id)});
  }
  return out;
}

Eigen::Isometry3d RobotNode::estimate(core::KeyframeId k) const {
  return impl_->estimate(k);
}

backend::PoseGraph RobotNode::graph() const {
  backend::PoseGraph g = impl_->mapper.graph();
  for (const core::Keyframe& k : impl_->mapper.keyframes())
    g.setEstimate({impl_->self, k.id}, impl_->estimate(k.id));
  for (const InterLoop& loop : interLoops()) {
    if (!loop.accepted) continue;
    const backend::Factor& f = loop.factor;
    const bool own_from = f.from.robot == impl_->self;
    const core::PoseKey& own = own_from ? f.from : f.to;
    const core::PoseKey& other = own_from ? f.to : f.from;
    if (!g.hasNode(other)) {
      const Eigen::Isometry3d T_own = impl_->estimate(own.keyframe);
      g.addNode(other, own_from ? T_own * f.T_from_to : T_own * f.T_from_to.inverse());
    }
    g.addFactor(f);
  }
  return g;
}

std::optional<core::RobotId> RobotNode::frame() const {
  return impl_->frame;
}

void RobotNode::stop() {
  Impl& i = *impl_;
  if (!i.round) return;
  if (!i.round->refine) return i.leave("dgs_rounds_left_at_stop");
  i.stopRefinement();
}

bool RobotNode::settled() const {
  const Impl& i = *impl_;
  if (i.round || i.last_round_capped) return false;
  const std::set<core::RobotId> members = i.group();
  if (members.size() < 2)
    return !i.config.solve_alone || i.anchors.empty() ||
           i.mapper.loops().size() == i.solved_own_loops;
  return i.signature(members) == i.last_signature;
}

double RobotNode::peersMappedAt() const {
  return impl_->peers_mapped_at;
}

const std::map<std::string, double>& RobotNode::counters() const {
  return impl_->counters;
}

const comm::Messenger& RobotNode::messenger() const {
  return impl_->messenger;
}

}  // namespace dcl::robot
