#include <algorithm>
#include <cmath>
#include <limits>
#include <optional>
#include <string>
#include <utility>

#include <spdlog/spdlog.h>

#include <dcl/backend/centralized_solver.hpp>
#include <dcl/backend/loop_check.hpp>
#include <dcl/backend/pcm_trajectory.hpp>
#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>
#include <dcl/place/descriptor_codec.hpp>
#include <dcl/place/lidar_iris.hpp>
#include <dcl/robot/dgs_wire.hpp>
#include <dcl/robot/robot_node.hpp>

namespace dcl::robot {
namespace {

using comm::Body;
using comm::Message;

/// "rejected_low_inlier_share", ... for the counters.
std::string refusalCounter(comm::LoopStatus status) {
  static constexpr const char* kNames[] = {"verified",
                                           "rejected_too_few_points",
                                           "rejected_not_converged",
                                           "rejected_low_inlier_share",
                                           "rejected_high_fitness",
                                           "rejected_degenerate",
                                           "rejected_no_submap",
                                           "rejected_bad_cloud",
                                           "unexplained",
                                           "rejected_symmetric",
                                           "repeated"};
  return kNames[static_cast<std::size_t>(status)];
}

/// The id of the loop between two robots' keyframes, the lower robot's first.
backend::LoopId pairLoop(const core::PoseKey& a, const core::PoseKey& b) {
  return a.robot < b.robot ? backend::LoopId{a, b} : backend::LoopId{b, a};
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

core::Matrix6d loopCovariance(const core::Matrix6d& registration, const RobotConfig& config) {
  core::Matrix6d covariance = registration;
  covariance.diagonal().head<3>().array() +=
      config.loop_sigma_translation * config.loop_sigma_translation;
  const double tilt = std::max(config.loop_sigma_tilt, config.loop_sigma_rotation);
  covariance.diagonal().tail<3>() += Eigen::Vector3d(
      tilt * tilt, tilt * tilt, config.loop_sigma_rotation * config.loop_sigma_rotation);
  return covariance;
}

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

namespace {

constexpr double kNever = -std::numeric_limits<double>::infinity();

/// What a robot announced of its loops.
struct Link {
  std::set<core::RobotId> neighbours;  ///< robots it shares accepted loops with
  std::uint32_t loops = 0;             ///< the loops it holds (loopsHeld)
};

using PoseMap = std::map<core::PoseKey, Eigen::Isometry3d>;

/// s a robot waiting in the refinement lets pass before sending its messages
/// of the step again (one may have been lost).
constexpr double kRefineResend = 0.04;
/// Finished rounds whose final refinement share is kept for members that lost it.
constexpr std::size_t kFinalSharesKept = 8;

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
/// A robot stopped while its round refines keeps the last kept step when the
/// cost fell by at most this share over the last kSettlingSteps kept steps.
constexpr double kSettlingDecrease = 0.02;
constexpr std::size_t kSettlingSteps = 10;

/// The distributed refinement after DGS, within a round.
struct Refinement {
  backend::RefineAgent agent;
  std::optional<backend::RefineSchedule> schedule;  ///< from step 0's total cost on
  std::uint32_t step = 0;                           ///< 0: the exchange of DGS's estimates
  bool stepped = false;                             ///< this robot's block step of `step` done
  bool shared = false;                              ///< its cost share of `step` sent
  std::set<core::RobotId> applied;                  ///< members whose values of `step` are in
  /// Neighbours whose step-0 message carried separators for this robot: the
  /// ones it waits for. A member whose loops changed after it joined may hold
  /// a loop this robot does not, or lack one it holds.
  std::set<core::RobotId> linked;
  std::vector<RefineMessage> sent;  ///< this step's messages and the last step's share
  double last_sent = 0.0;
  /// Per linked neighbour: the step of the last separators sent to it, and
  /// their values as it decodes them (the base of the next step's increments).
  std::map<core::RobotId, std::pair<std::uint32_t, PoseMap>> told;
};

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

/// A DGS round this robot takes part in.
struct Round {
  std::uint32_t number = 0;  ///< the initiator's counter << 8 | the initiator's id
  std::set<core::RobotId> group;
  /// The robot whose first keyframe anchors the round (the initiator's frame:
  /// DGS holds the lowest member's first pose where it is), and whether the
  /// refinement starts from the members' current estimates.
  RoundOrigin origin;
  backend::DgsAgent agent;
  /// When the round last moved on (joined, a DGS step, a refinement step):
  /// a round is given up only when it stalls, not when it is long (a group of
  /// 27 robots takes up to half a second a refinement step).
  double progressed = 0.0;
  backend::PoseGraph graph;  ///< the own part of the graph it optimises
  /// Per member heard from in this round: its latest DGS step, and whether it
  /// has left DGS (its last stage finished).
  std::map<core::RobotId, std::pair<int, bool>> heard;
  double waiting_since = 0.0;  ///< when this robot began to wait for a member's step
  std::optional<Refinement> refine;
  /// Refinement messages received, by step (a member may be a step ahead, or
  /// already refining while DGS still runs here).
  std::map<std::uint32_t, std::map<core::RobotId, PoseMap>> values;
  std::map<std::uint32_t, std::map<core::RobotId, float>> shares;
  std::size_t own_loops = 0;  ///< the own intra-robot loops when it began
  /// Per member: the step of the last refinement values taken in from it, and
  /// those values (the base its next step's increments apply to).
  std::map<core::RobotId, std::pair<std::uint32_t, PoseMap>> decoded;
  double dgs_last_sent = 0.0;  ///< when its last DGS step's messages went out
};

std::uint8_t initiator(std::uint32_t round) {
  return static_cast<std::uint8_t>(round & 0xFFU);
}

}  // namespace

/// What this robot knows of one neighbour it has heard descriptors from.
struct Neighbour {
  explicit Neighbour(backend::PairwiseConsistency consistency) : pcm(std::move(consistency)) {}
  backend::PairwiseConsistency pcm;
  /// (own, theirs) candidates sent, with the match distance of theirs to own.
  std::map<std::pair<core::KeyframeId, core::KeyframeId>, float> asked;
  /// The neighbour's descriptors of those candidates, to judge them again.
  std::map<core::KeyframeId, std::shared_ptr<const place::IrisDescriptor>> asked_descriptors;
  std::map<backend::LoopId, backend::Factor> loops;  ///< verified, by either side
  std::set<backend::LoopId> accepted;                ///< PCM's current set
  /// The loops of this pair that a round's solution did not explain, by
  /// round: as this robot saw them, and as the neighbour gave notice of them.
  std::map<std::uint32_t, std::set<backend::LoopId>> own_unexplained;
  std::map<std::uint32_t, std::set<backend::LoopId>> their_unexplained;
};

struct RobotNode::Impl {
  core::RobotId self;
  RobotConfig config;
  comm::Messenger messenger;
  std::unique_ptr<odometry::Odometry> odometry;  ///< the front-end
  odometry::LocalMapper mapper;
  place::IrisConfig iris;
  std::shared_ptr<const place::Descriptor> descriptor;
  place::PlaceIndex index;
  std::map<core::RobotId, Neighbour> neighbours;
  std::vector<backend::Factor> own_chain;  ///< odometry steps as the neighbours read them
  std::map<std::string, double> counters;
  double now = 0.0;
  // Optimisation rounds.
  std::map<core::RobotId, Link> links;
  std::optional<Round> round;
  std::set<std::uint32_t> finished;  ///< rounds this robot took part in and left
  /// Of those, the rounds it left before they were done (abandoned, or ended
  /// early): a member still in one is told so when it is heard from.
  std::set<std::uint32_t> abandoned;
  std::uint32_t rounds_started = 0;
  double last_round_start = kNever;  ///< when this robot last joined a round
  double last_announce = kNever;
  std::vector<std::pair<core::RobotId, std::uint32_t>> last_signature;
  std::size_t loops_replaced = 0;  ///< inter-robot loops replaced by the lower robot's measurement
  std::map<core::KeyframeId, Eigen::Isometry3d> optimised;  ///< own poses after the last round
  /// The robot whose first keyframe anchors the own estimates: this robot's
  /// until a round places it, then that round's. None: a round of unknown frame.
  std::optional<core::RobotId> frame;
  /// The last round finished on its step cap, not converged: the group goes
  /// on with it (a warm round) even if no loop changed.
  bool last_round_capped = false;
  /// The cost share of the step at which each recent round's refinement ended:
  /// a member whose copy was lost still waits for it, and asks by sending its own.
  std::map<std::uint32_t, RefineMessage> final_shares;
  /// The neighbours' separator poses where the rounds in `frame` left them,
  /// and the inter-robot loops of those rounds: what holds this robot to its
  /// neighbours when it solves alone.
  PoseMap anchors;
  std::set<backend::LoopId> anchored_loops;
  /// The own intra-robot loops when the estimates were last solved.
  std::size_t solved_own_loops = 0;
  double last_solved_alone = kNever;

  Impl(comm::Transport& transport, const RobotConfig& c, std::uint32_t incarnation,
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

  void count(const std::string& name, double amount = 1.0) { counters[name] += amount; }

  // ---- own scans and keyframes ------------------------------------------

  void addScan(double stamp, const core::PointCloud& scan) {
    count("frames");
    const odometry::OdometryResult result = odometry->process(stamp, scan);
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
    const auto alikes = index.lookAlikes(*description, keyframe.T_odom_keyframe.translation(),
                                         ownPosition(), index.size());
    index.add(keyframe.id, description);
    comm::DescriptorMessage m{keyframe.id,  keyframe.stamp, place::encodeIris(*description),
                              std::nullopt, std::nullopt,   {}};
    if (!alikes.empty()) m.look_alike = alikes.front().second;
    for (const auto& [earlier, distance] : alikes) {
      if (m.resembles.size() == comm::kMaxResemblances) break;
      m.resembles.push_back({earlier, distance});
    }
    if (keyframe.id.value() > 0)
      m.odometry = comm::OdometryStep{core::KeyframeId(keyframe.id.value() - 1),
                                      keyframe.T_previous_keyframe, keyframe.covariance};
    // PCM checks the own chain as the neighbours read it (both sides decide alike).
    m = std::get<comm::DescriptorMessage>(comm::asDelivered(m));
    for (auto& [robot, n] : neighbours)
      for (const comm::Resemblance& r : m.resembles)
        judgeOwnRepeat(robot, n, r.keyframe, *description);
    if (m.odometry) {
      const backend::Factor step = odometryFactor(self, keyframe.id, *m.odometry);
      own_chain.push_back(step);
      for (auto& [robot, n] : neighbours) {
        n.pcm.addRobotFactor(step);
        redecideIfRejecting(n);
      }
    }
    messenger.send(std::nullopt, std::move(m), now);
    count("descriptors_sent");
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
  /// on the route: the loops to `robot` asked at `earlier` are judged again.
  void judgeOwnRepeat(core::RobotId robot, Neighbour& n, core::KeyframeId earlier,
                      const place::PlaceDescriptor& later) {
    for (auto it = n.asked.lower_bound({earlier, core::KeyframeId(0)});
         it != n.asked.end() && it->first.first == earlier; ++it) {
      const auto theirs = n.asked_descriptors.find(it->first.second);
      if (theirs == n.asked_descriptors.end()) continue;
      judgeRepeat(robot, n, it->first, it->second, descriptor->match(*theirs->second, later));
    }
  }

  /// Neighbour `robot`'s new keyframe (described by `later`) resembles its
  /// keyframe `earlier`, far from it on its route: the loops asked at
  /// `earlier` are judged again.
  void judgeTheirRepeat(core::RobotId robot, Neighbour& n, core::KeyframeId earlier,
                        const place::PlaceDescriptor& later) {
    for (const auto& [pair, distance] : n.asked) {
      if (pair.second != earlier) continue;
      const place::PlaceDescriptor& own = index.description(pair.first.value());
      judgeRepeat(robot, n, pair, distance, descriptor->match(later, own));
    }
  }

  /// Withdraws the loop asked as `pair` (own, theirs) with match distance
  /// `distance` when a repeat of either place matches within
  /// PlaceIndexConfig::distinct_ratio of it (`repeat`), and tells `robot`.
  void judgeRepeat(core::RobotId robot, Neighbour& n,
                   const std::pair<core::KeyframeId, core::KeyframeId>& pair, double distance,
                   const place::Match& repeat) {
    if (static_cast<double>(distance) < config.index.distinct_ratio * repeat.distance) {
      spdlog::trace("robot {}: t {:.1f}: keeps the loop {}{} - {}{}: match {:.3f}, a repeat {:.3f}",
                    core::robotName(self), now, core::robotName(self), pair.first.value(),
                    core::robotName(robot), pair.second.value(), distance, repeat.distance);
      return;
    }
    const core::PoseKey own{self, pair.first};
    const core::PoseKey theirs{robot, pair.second};
    if (!n.pcm.withdraw(pairLoop(own, theirs))) return;
    comm::LoopMeasurement notice{pair.second, pair.first, comm::LoopStatus::repeated};
    messenger.send(robot, notice, now);
    count("inter_loops_withdrawn_repeated");
    spdlog::debug(
        "robot {}: t {:.1f}: withdraws the loop {}{} - {}{}: match {:.3f}, a repeat {:.3f}",
        core::robotName(self), now, core::robotName(self), pair.first.value(),
        core::robotName(robot), pair.second.value(), distance, repeat.distance);
    decide(n);
    forgetFrameIfUnlinked();
  }

  /// A notice from `from`: it withdrew loop (m.match of theirs, m.query of
  /// this robot's), a repeated place's.
  void onRepeated(core::RobotId from, const comm::LoopMeasurement& m) {
    count("repeated_notices_received");
    Neighbour& n = neighbour(from);
    const core::PoseKey theirs{from, m.match};
    const core::PoseKey mine{self, m.query};
    if (!n.pcm.withdraw(pairLoop(mine, theirs))) return;
    count("inter_loops_withdrawn_repeated");
    decide(n);
    forgetFrameIfUnlinked();
  }

  /// Where the own odometry puts an own keyframe (the place index's positions).
  [[nodiscard]] place::KeyframePosition ownPosition() const {
    return [this](core::KeyframeId id) {
      return Eigen::Vector3d(mapper.keyframes().at(id.value()).T_odom_keyframe.translation());
    };
  }

  /// The odometry factors of the own keyframes so far (for a new PCM pair).
  void addOwnChain(backend::PairwiseConsistency& pcm) const {
    for (const backend::Factor& step : own_chain) pcm.addRobotFactor(step);
  }

  Neighbour& neighbour(core::RobotId robot) {
    auto it = neighbours.find(robot);
    if (it != neighbours.end()) return it->second;
    const core::RobotId a = std::min(self, robot);
    const core::RobotId b = a == self ? robot : self;
    it = neighbours.emplace(robot, Neighbour(backend::PairwiseConsistency(a, b, config.pcm))).first;
    addOwnChain(it->second.pcm);
    return it->second;
  }

  // ---- messages ----------------------------------------------------------

  void tick(double time) {
    now = time;
    for (const Message& m : messenger.poll(now)) handle(m);
    announce();
    maybeStartRound();
    stepRound();
    maybeSolveAlone();
  }

  void handle(const Message& m) {
    const core::RobotId from = m.header.sender;
    if (const auto* d = std::get_if<comm::DescriptorMessage>(&m.body))
      return onDescriptor(from, *d);
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

  /// Stage 1 received: the neighbour's chain grows; the own index is searched.
  void onDescriptor(core::RobotId from, const comm::DescriptorMessage& d) {
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
    for (const comm::Resemblance& r : d.resembles) judgeTheirRepeat(from, n, r.keyframe, *theirs);
    const place::DistinctMatch found = index.queryDistinct(*theirs, ownPosition(), d.look_alike);
    if (found.refused) count("candidates_ambiguous");
    const std::optional<place::PlaceCandidate>& best = found.best;
    if (!best) return;
    const core::KeyframeId own = best->keyframe.keyframe;
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
  [[nodiscard]] bool askedNearby(const Neighbour& n, core::KeyframeId own,
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
    // Keep the loop as the querying robot will read it, so both hold the same factor.
    answer = std::get<comm::LoopMeasurement>(comm::asDelivered(answer));
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
    answer.status = v.reason == registration::RejectReason::symmetric
                        ? comm::LoopStatus::symmetric
                        : static_cast<comm::LoopStatus>(v.reason);  // the same order to degenerate
    answer.T_match_query = v.T_candidate_query;
    answer.covariance = loopCovariance(v.covariance, config);
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
    if (m.status == comm::LoopStatus::unexplained) return onUnexplained(from, m);
    if (m.status == comm::LoopStatus::repeated) return onRepeated(from, m);
    count(m.status == comm::LoopStatus::verified ? "measurements_verified"
                                                 : "measurements_refused");
    if (m.status != comm::LoopStatus::verified) return;
    addLoop(from, loopFactor(from, self, m));
  }

  /// A loop the verifier `f.from.robot` measured. Two robots that sent each
  /// other a candidate for the same two keyframes each verify it: both then
  /// keep the lower robot's measurement, whichever arrived first, so that the
  /// two hold, check and optimise the same factor. (Each keeping the one that
  /// came last, each other's, they pulled a round's refinement against each
  /// other: campus-9 seed 3 ended at 2.5 times the optimum's chi-square.)
  void addLoop(core::RobotId other, const backend::Factor& f) {
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

  void decide(Neighbour& n) {
    const backend::PcmDecision& decision = n.pcm.decide();
    n.accepted.clear();
    for (const backend::Factor& a : decision.accepted) n.accepted.insert(backend::loopId(a));
    recountPcm();
  }

  /// A chain grew: loops PCM could not yet relate (the steps between them had
  /// not all arrived) are judged again, so both robots of the pair end with the
  /// same decision whatever order loops and descriptors came in.
  void redecideIfRejecting(Neighbour& n) {
    if (n.accepted.size() < n.loops.size()) decide(n);
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

  // ---- optimisation rounds ------------------------------------------------

  [[nodiscard]] std::set<core::RobotId> loopNeighbours() const {
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
  [[nodiscard]] std::uint32_t loopsHeld() const {
    std::size_t accepted = mapper.loops().size() + loops_replaced;
    for (const auto& [robot, n] : neighbours) accepted += n.accepted.size();
    return static_cast<std::uint32_t>(accepted);
  }

  /// Tells everyone in range which robots this one shares loops with.
  void announce() {
    if (now - last_announce < config.announce_period) return;
    last_announce = now;
    comm::DgsState state;
    state.stage = comm::OptimisationStage::idle;
    state.iteration = loopsHeld();
    for (const core::RobotId robot : loopNeighbours()) state.progress.push_back({robot});
    if (state.progress.empty()) return;
    messenger.send(std::nullopt, std::move(state), now);
  }

  void onAnnouncement(core::RobotId from, const comm::DgsState& state) {
    Link& link = links[from];
    link.neighbours.clear();
    for (const comm::MemberProgress& p : state.progress) link.neighbours.insert(p.robot);
    link.loops = state.iteration;
  }

  /// The robots in range joined to this one by loops, as announced.
  [[nodiscard]] std::set<core::RobotId> group() const {
    const std::set<core::RobotId> present = messenger.neighbours();
    std::set<core::RobotId> members{self};
    std::vector<core::RobotId> todo{self};
    while (!todo.empty()) {
      const core::RobotId r = todo.back();
      todo.pop_back();
      std::set<core::RobotId> next = r == self ? loopNeighbours() : std::set<core::RobotId>{};
      if (const auto it = links.find(r); it != links.end() && r != self)
        next = it->second.neighbours;
      for (const core::RobotId n : next) {
        if ((n == self || present.contains(n)) && members.insert(n).second) todo.push_back(n);
      }
    }
    return members;
  }

  /// True when the loops of `current` number half as many again as those of
  /// the last round's signature (none: false).
  [[nodiscard]] bool grewByHalf(
      const std::vector<std::pair<core::RobotId, std::uint32_t>>& current) const {
    const auto total = [](const auto& signature) {
      std::uint64_t sum = 0;
      for (const auto& [robot, loops] : signature) sum += loops;
      return sum;
    };
    const std::uint64_t last = total(last_signature);
    return last > 0 && 2 * total(current) >= 3 * last;
  }

  [[nodiscard]] std::vector<std::pair<core::RobotId, std::uint32_t>> signature(
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
  void maybeStartRound() {
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

  /// The own keyframes at their latest estimates, with the own factors
  /// (odometry and intra-robot loops).
  [[nodiscard]] backend::PoseGraph ownGraph() const {
    backend::PoseGraph g;
    for (const core::Keyframe& k : mapper.keyframes()) g.addNode({self, k.id}, estimate(k.id));
    for (const backend::Factor& f : mapper.graph().factors()) g.addFactor(f);
    return g;
  }

  /// The own part of the graph a round optimises: own poses at their latest
  /// estimates, own factors, the accepted loops to the group's members, and,
  /// in a round in the current frame, the loops to robots out of the group
  /// held where the rounds in this frame left those robots (hold_absent):
  /// what the round moves stays where they placed their maps, so the swarm's
  /// maps still agree when they cannot hear of it. Held loops anchor the
  /// round's gauge, in DGS and in the refinement, where the lowest member's
  /// first pose would otherwise be pinned: the two would pull apart.
  [[nodiscard]] backend::PoseGraph roundGraph(const std::set<core::RobotId>& members,
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

  void join(std::uint32_t number, const std::set<core::RobotId>& members,
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
  void leave(const char* why, bool soon = false) {
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

  void onDgs(const backend::DgsMessage& m, const RoundOrigin& origin) {
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

  void sendDgs(const backend::DgsMessage& m) {
    messenger.send(m.to, withMembers(toWire(m), round->group, round->origin), now);
  }

  /// One DGS step a tick, then the refinement; the estimates taken when the round is done.
  void stepRound() {
    if (!round) return;
    const std::set<core::RobotId> present = messenger.neighbours();
    const bool whole = std::all_of(round->group.begin(), round->group.end(), [&](core::RobotId r) {
      return r == self || present.contains(r);
    });
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
  [[nodiscard]] bool membersInStep() {
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

  void resendDgsStep() {
    const std::vector<backend::DgsMessage> last = round->agent.outgoing();
    if (last.empty() || now - round->dgs_last_sent < kDgsResend) return;
    for (const backend::DgsMessage& m : last) sendDgs(m);
    round->dgs_last_sent = now;
    count("dgs_resent", static_cast<double>(last.size()));
  }

  /// Ends the round's refinement before its schedule did (a member gone
  /// silent): DGS's estimate and every kept refinement step are consistent
  /// in the group, so the last kept one is taken rather than nothing.
  void endRefinementEarly(const char* why) {
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
  void stopRefinement() {
    const std::optional<backend::RefineSchedule>& schedule = round->refine->schedule;
    const std::vector<double>* costs = schedule ? &schedule->roundCosts() : nullptr;
    const bool settling = costs != nullptr && costs->size() >= kSettlingSteps &&
                          (*costs)[costs->size() - kSettlingSteps] - costs->back() <=
                              kSettlingDecrease * costs->back();
    if (!settling) return leave("rounds_left_unsettled_at_stop");
    endRefinementEarly("rounds_ended_by_stop");
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
  void checkRoundLoops(const PoseMap& own, const PoseMap& members) {
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
  void onUnexplained(core::RobotId from, const comm::LoopMeasurement& m) {
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
  void withdrawIfBothSaw(core::RobotId partner, Neighbour& n, std::uint32_t round_number) {
    const auto own = n.own_unexplained.find(round_number);
    const auto theirs = n.their_unexplained.find(round_number);
    if (own != n.own_unexplained.end() && theirs != n.their_unexplained.end()) {
      std::size_t withdrawn = 0;
      for (const auto* ids : {&own->second, &theirs->second})
        for (const backend::LoopId& id : *ids) withdrawn += n.pcm.withdraw(id) ? 1 : 0;
      if (withdrawn > 0) {
        count("inter_loops_withdrawn", static_cast<double>(withdrawn));
        spdlog::debug("robot {}: t {:.1f}: withdraws {} loops to {} (round {})",
                      core::robotName(self), now, withdrawn, core::robotName(partner),
                      round_number);
        decide(n);
        forgetFrameIfUnlinked();
      }
    }
    constexpr std::size_t kRoundsKept = 8;
    while (n.own_unexplained.size() > kRoundsKept)
      n.own_unexplained.erase(n.own_unexplained.begin());
    while (n.their_unexplained.size() > kRoundsKept)
      n.their_unexplained.erase(n.their_unexplained.begin());
  }

  /// No loop to a neighbour is left (every one withdrawn) and no round is
  /// running: nothing holds the own map in another robot's frame, or bent
  /// towards a neighbour's, any more. The estimates go back to the own local
  /// graph's, in the own frame, as if no round had placed them; a later loop
  /// starts over from there.
  void forgetFrameIfUnlinked() {
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

  void finishRound(const PoseMap& estimates, bool capped = false) {
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

  // ---- alone ------------------------------------------------------------------

  /// Own loops closed since the estimates were last solved, and no one in
  /// range to optimise with: the own graph is solved with the inter-robot
  /// loops of the rounds in the current frame, the neighbours' poses held
  /// where those rounds left them (the refinement's block problem, solved to
  /// convergence by the centralized solver). Inter-robot loops no round has held yet wait for one:
  /// both robots would take each in full against the other's old poses, and together overshoot. A
  /// robot that never shared a round has nothing to solve: its own loops are already in its local
  /// graph's estimates.
  void maybeSolveAlone() {
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
  std::size_t addHeldLoops(backend::PoseGraph& g, const std::set<core::RobotId>& members) const {
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

  // ---- the refinement within a round ----------------------------------------

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
  void startRefinement() {
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

  void onRefine(const RefineMessage& m) {
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

  /// Tells `to` (everyone in range: none) that this robot left round `number`
  /// before it was done: the round cannot be finished without it (its
  /// refinement adds up every member's share), and a member still in it
  /// would wait for its steps until the round timed out. Nothing for a
  /// round this robot finished.
  void tellAbandoned(std::optional<core::RobotId> to, std::uint32_t number) {
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
  void onAbort(core::RobotId from, std::uint32_t number) {
    if (!round || round->number != number) {
      finished.insert(number);
      return;
    }
    if (!round->group.contains(from)) return;
    if (round->refine) return endRefinementEarly("refine_ended_by_member");
    leave("dgs_rounds_left_by_member", true);
  }

  /// A member still at the step at which this robot's refinement of a finished
  /// round ended lost this robot's share of it: it gets the share again.
  void answerLateMember(const RefineMessage& m) {
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
  void tellDgsMemberLeft(core::RobotId member) {
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

  void send(RefineMessage m) {
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
  void sendValues() {
    Refinement& r = *round->refine;
    const std::map<core::RobotId, std::set<core::PoseKey>>& separators = r.agent.separators();
    for (const core::RobotId member : round->group) {
      if (member == self || (r.step > 0 && !r.linked.contains(member))) continue;
      RefineMessage m{self, member, round->number, r.step, {}, std::nullopt, false};
      if (const auto it = separators.find(member); it != separators.end()) {
        for (const core::PoseKey& key : it->second)
          m.poses.emplace(key, r.agent.estimates().at(key));
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
  bool takeValues(const std::set<core::RobotId>& robots) {
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
  void advanceRefinement() {
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
        final_shares[round->number] = {self, self, round->number, r.step, {}, shares.at(self),
                                       false};
        while (final_shares.size() > kFinalSharesKept) final_shares.erase(final_shares.begin());
        count("refine_steps", r.schedule->rounds());
        count("refine_restarts", r.schedule->restarts());
        if (r.schedule->rounds() > 0)
          counters["refine_cost_ratio_last"] =
              r.schedule->cost() / r.schedule->roundCosts().front();
        checkRoundLoops(r.agent.estimates(), r.agent.neighbourValues());
        return finishRound(r.agent.estimates(), !r.schedule->converged());
      }
      nextStep(r);
    }
  }

  void nextStep(Refinement& r) {
    round->values.erase(r.step);
    round->shares.erase(r.step);
    // Keep the share just sent: a member still waiting for it may have lost it.
    std::erase_if(r.sent,
                  [&](const RefineMessage& m) { return !m.cost_share || m.step != r.step; });
    ++r.step;
    round->progressed = now;
    r.stepped = false;
    r.shared = false;
    r.applied.clear();
    r.agent.beginRound(r.schedule->momentum());
  }

  void resendWhenStalled() {
    Refinement& r = *round->refine;
    if (now - r.last_sent < kRefineResend) return;
    for (const RefineMessage& m : r.sent) messenger.send(m.to, toWire(m), now);
    r.last_sent = now;
    count("refine_resent", static_cast<double>(r.sent.size()));
  }

  /// The latest estimate of own keyframe `k`: optimised, or carried from the
  /// last optimised keyframe before it by the local graph's relative poses.
  [[nodiscard]] Eigen::Isometry3d estimate(core::KeyframeId k) const {
    const std::vector<Eigen::Isometry3d>& local = mapper.smoothedPoses();
    const Eigen::Isometry3d& T_local = local.at(k.value());
    auto it = optimised.upper_bound(k);
    if (it == optimised.begin()) return T_local;
    --it;
    return it->second * local.at(it->first.value()).inverse() * T_local;
  }
};

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

const std::map<std::string, double>& RobotNode::counters() const {
  return impl_->counters;
}

const comm::Messenger& RobotNode::messenger() const {
  return impl_->messenger;
}

}  // namespace dcl::robot
