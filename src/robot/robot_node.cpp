#include <algorithm>
#include <optional>
#include <string>
#include <utility>

#include <dcl/backend/pcm_trajectory.hpp>
#include <dcl/core/error.hpp>
#include <dcl/place/descriptor_codec.hpp>
#include <dcl/place/lidar_iris.hpp>
#include <dcl/robot/robot_node.hpp>

namespace dcl::robot {
namespace {

using comm::Body;
using comm::Message;

core::RobotId lower(core::RobotId a, core::RobotId b) {
  return std::min(a, b);
}

/// "rejected_low_inlier_share", ... for the counters.
std::string refusalCounter(comm::LoopStatus status) {
  static constexpr const char* kNames[] = {"verified",
                                           "rejected_too_few_points",
                                           "rejected_not_converged",
                                           "rejected_low_inlier_share",
                                           "rejected_high_fitness",
                                           "rejected_degenerate",
                                           "rejected_no_submap",
                                           "rejected_bad_cloud"};
  return kNames[static_cast<std::size_t>(status)];
}

backend::Factor odometryFactor(core::RobotId robot, core::KeyframeId keyframe,
                               const comm::OdometryStep& step) {
  backend::Factor f;
  f.from = {robot, step.previous};
  f.to = {robot, keyframe};
  f.T_from_to = step.T_previous_keyframe;
  f.information = backend::informationFromCovariance(step.covariance);
  f.kind = backend::FactorKind::odometry;
  return f;
}

}  // namespace

void validate(const RobotConfig& config) {
  if (config.descriptor.kind != "iris")
    throw core::Error("robot config: descriptor.kind '" + config.descriptor.kind +
                      "': robots exchange LiDAR-Iris descriptors only (the wire codec's)");
  place::validate(config.descriptor.iris);
  registration::validate(config.verification);
  comm::validate(config.messenger);
}

/// What this robot knows of one neighbour it has heard descriptors from.
struct Neighbour {
  explicit Neighbour(backend::PairwiseConsistency consistency) : pcm(std::move(consistency)) {}
  backend::PairwiseConsistency pcm;
  std::set<std::pair<core::KeyframeId, core::KeyframeId>> asked;  ///< (own, theirs) candidates sent
  std::map<backend::LoopId, backend::Factor> loops;               ///< verified, by either side
  std::set<backend::LoopId> accepted;                             ///< PCM's current set
};

struct RobotNode::Impl {
  core::RobotId self;
  RobotConfig config;
  comm::Messenger messenger;
  odometry::LidarOdometry odometry;
  odometry::LocalMapper mapper;
  place::IrisConfig iris;
  std::shared_ptr<const place::Descriptor> descriptor;
  place::PlaceIndex index;
  std::map<core::RobotId, Neighbour> neighbours;
  std::map<std::string, double> counters;
  double now = 0.0;

  Impl(comm::Transport& transport, const RobotConfig& c, std::uint32_t incarnation)
      : self(transport.self()),
        config(c),
        messenger(transport, incarnation, c.messenger),
        odometry(c.odometry),
        mapper(transport.self(), c.mapper),
        iris(c.descriptor.iris),
        descriptor(place::makeDescriptor(c.descriptor)),
        index(descriptor, transport.self(), c.index) {
    validate(config);
    config.pcm.intra_loops = false;
  }

  void count(const std::string& name, double amount = 1.0) { counters[name] += amount; }

  // ---- own scans and keyframes ------------------------------------------

  void addScan(double stamp, const core::PointCloud& scan) {
    count("frames");
    const odometry::OdometryResult result = odometry.process(stamp, scan);
    const odometry::MapperUpdate update =
        result.registered.empty() ? mapper.process(result, scan) : mapper.process(result);
    if (update.loop) count("intra_loops");
    if (update.keyframe) onKeyframe(mapper.keyframes().back());
  }

  void onKeyframe(const core::Keyframe& keyframe) {
    count("keyframes");
    messenger.setKeyframes(static_cast<std::uint32_t>(mapper.keyframes().size()));
    auto description =
        std::make_shared<const place::IrisDescriptor>(place::describeIris(keyframe.cloud, iris));
    index.add(keyframe.id, description);
    comm::DescriptorMessage m{keyframe.id, keyframe.stamp, place::encodeIris(*description),
                              std::nullopt};
    if (keyframe.id.value() > 0) {
      m.odometry = comm::OdometryStep{core::KeyframeId(keyframe.id.value() - 1),
                                      keyframe.T_previous_keyframe, keyframe.covariance};
      for (auto& [robot, n] : neighbours)
        n.pcm.addRobotFactor(odometryFactor(self, keyframe.id, *m.odometry));
    }
    messenger.send(std::nullopt, std::move(m), now);
    count("descriptors_sent");
  }

  /// The odometry factors of the own keyframes so far (for a new PCM pair).
  void addOwnChain(backend::PairwiseConsistency& pcm) const {
    for (const core::Keyframe& k : mapper.keyframes()) {
      if (k.id.value() == 0) continue;
      pcm.addRobotFactor(odometryFactor(self, k.id,
                                        comm::OdometryStep{core::KeyframeId(k.id.value() - 1),
                                                           k.T_previous_keyframe, k.covariance}));
    }
  }

  Neighbour& neighbour(core::RobotId robot) {
    auto it = neighbours.find(robot);
    if (it != neighbours.end()) return it->second;
    const core::RobotId a = lower(self, robot);
    const core::RobotId b = a == self ? robot : self;
    it = neighbours.emplace(robot, Neighbour(backend::PairwiseConsistency(a, b, config.pcm))).first;
    addOwnChain(it->second.pcm);
    return it->second;
  }

  // ---- messages ----------------------------------------------------------

  void tick(double time) {
    now = time;
    for (const Message& m : messenger.poll(now)) handle(m);
  }

  void handle(const Message& m) {
    const core::RobotId from = m.header.sender;
    if (const auto* d = std::get_if<comm::DescriptorMessage>(&m.body))
      return onDescriptor(from, *d);
    if (const auto* c = std::get_if<comm::LoopCandidate>(&m.body)) return onCandidate(from, *c);
    if (const auto* l = std::get_if<comm::LoopMeasurement>(&m.body)) return onMeasurement(from, *l);
  }

  /// Stage 1 received: the neighbour's chain grows; the own index is searched.
  void onDescriptor(core::RobotId from, const comm::DescriptorMessage& d) {
    count("descriptors_received");
    Neighbour& n = neighbour(from);
    if (d.odometry) n.pcm.addRobotFactor(odometryFactor(from, d.keyframe, *d.odometry));
    std::shared_ptr<const place::IrisDescriptor> theirs;
    try {
      theirs = std::make_shared<const place::IrisDescriptor>(place::decodeIris(d.descriptor, iris));
    } catch (const core::Error&) {
      count("descriptors_undecodable");
      return;
    }
    const std::optional<place::PlaceCandidate> best = index.query(*theirs);
    if (!best) return;
    const core::KeyframeId own = best->keyframe.keyframe;
    if (!n.asked.emplace(own, d.keyframe).second) return;
    sendCandidate(from, own, d.keyframe, best->match);
  }

  /// Stage 2: the own keyframe's compact cloud to the robot owning the place.
  void sendCandidate(core::RobotId to, core::KeyframeId own, core::KeyframeId theirs,
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

  /// Stage 2 received: verify against the own submap; stage 3 back.
  void onCandidate(core::RobotId from, const comm::LoopCandidate& c) {
    count("candidates_received");
    comm::LoopMeasurement answer{c.query, c.match, comm::LoopStatus::no_submap};
    if (c.match.value() < mapper.keyframes().size()) {
      answer = verify(c);
    }
    count(refusalCounter(answer.status));
    if (answer.status == comm::LoopStatus::verified) addLoop(from, loopFactor(self, from, answer));
    messenger.send(from, answer, now);
  }

  comm::LoopMeasurement verify(const comm::LoopCandidate& c) {
    comm::LoopMeasurement answer{c.query, c.match, comm::LoopStatus::bad_cloud};
    core::PointCloud query;
    try {
      query = registration::decodeVerificationCloud(c.cloud);
    } catch (const core::Error&) {
      return answer;
    }
    const registration::VerificationConfig& vc = config.verification;
    const core::PointCloud submap = registration::buildSubmap(mapper.keyframes(), c.match.value(),
                                                              vc.submap_keyframes, vc.voxel_size);
    const registration::VerificationResult v = registration::verifyLoop(query, c.yaw, submap, vc);
    answer.status = static_cast<comm::LoopStatus>(v.reason);  // the same order, none = verified
    answer.T_match_query = v.T_candidate_query;
    answer.covariance = v.covariance;
    return answer;
  }

  /// The loop factor from the verifying robot's keyframe to the querying one's.
  static backend::Factor loopFactor(core::RobotId verifier, core::RobotId querier,
                                    const comm::LoopMeasurement& m) {
    backend::Factor f;
    f.from = {verifier, m.match};
    f.to = {querier, m.query};
    f.kind = backend::FactorKind::inter_loop;
    f.T_from_to = m.T_match_query;
    f.information = backend::informationFromCovariance(m.covariance);
    return f;
  }

  /// Stage 3 received: the neighbour verified one of the own candidates.
  void onMeasurement(core::RobotId from, const comm::LoopMeasurement& m) {
    count(m.status == comm::LoopStatus::verified ? "measurements_verified"
                                                 : "measurements_refused");
    if (m.status != comm::LoopStatus::verified) return;
    addLoop(from, loopFactor(from, self, m));
  }

  void addLoop(core::RobotId other, const backend::Factor& f) {
    Neighbour& n = neighbour(other);
    n.loops[backend::loopId(f)] = f;
    (void)n.pcm.addLoop(f);
    const backend::PcmDecision& decision = n.pcm.decide();
    n.accepted.clear();
    for (const backend::Factor& a : decision.accepted) n.accepted.insert(backend::loopId(a));
    recountPcm();
  }

  void recountPcm() {
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
};

RobotNode::RobotNode(comm::Transport& transport, const RobotConfig& config,
                     std::uint32_t incarnation)
    : impl_(std::make_unique<Impl>(transport, config, incarnation)) {}
RobotNode::~RobotNode() = default;

core::RobotId RobotNode::id() const {
  return impl_->self;
}

void RobotNode::addScan(double stamp, const core::PointCloud& scan) {
  impl_->addScan(stamp, scan);
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

backend::PoseGraph RobotNode::graph() const {
  backend::PoseGraph g = impl_->mapper.graph();
  for (const InterLoop& loop : interLoops()) {
    if (!loop.accepted) continue;
    for (const core::PoseKey& end : {loop.factor.from, loop.factor.to}) {
      if (!g.hasNode(end)) g.addNode(end, Eigen::Isometry3d::Identity());
    }
    g.addFactor(loop.factor);
  }
  return g;
}

const std::map<std::string, double>& RobotNode::counters() const {
  return impl_->counters;
}

const comm::Messenger& RobotNode::messenger() const {
  return impl_->messenger;
}

}  // namespace dcl::robot
