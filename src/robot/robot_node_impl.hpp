#pragma once

/// The state of one robot node (RobotNode::Impl) and the helpers its stages
/// share. Internal to the robot module: each stage's methods are defined in
/// the source file named in this struct, robot_node.cpp holds the
/// construction, the message dispatch and the public methods.

#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <dcl/backend/dgs.hpp>
#include <dcl/backend/distributed_refine.hpp>
#include <dcl/backend/pcm.hpp>
#include <dcl/backend/pose_graph.hpp>
#include <dcl/comm/messages.hpp>
#include <dcl/comm/messenger.hpp>
#include <dcl/core/ids.hpp>
#include <dcl/place/lidar_iris.hpp>
#include <dcl/place/place_index.hpp>
#include <dcl/robot/dgs_wire.hpp>
#include <dcl/robot/robot_node.hpp>

namespace dcl::robot {
namespace detail {

/// The id of the loop between two robots' keyframes, the lower robot's first.
inline backend::LoopId pairLoop(const core::PoseKey& a, const core::PoseKey& b) {
  return a.robot < b.robot ? backend::LoopId{a, b} : backend::LoopId{b, a};
}

inline backend::Factor odometryFactor(core::RobotId robot, core::KeyframeId keyframe,
                                      const comm::OdometryStep& step) {
  backend::Factor f;
  f.from = {robot, step.previous};
  f.to = {robot, keyframe};
  f.T_from_to = step.T_previous_keyframe;
  f.information = backend::informationFromCovariance(step.covariance);
  f.kind = backend::FactorKind::odometry;
  return f;
}

inline constexpr double kNever = -std::numeric_limits<double>::infinity();

/// What a robot announced of its loops.
struct Link {
  std::set<core::RobotId> neighbours;  ///< robots it shares accepted loops with
  std::uint32_t loops = 0;             ///< the loops it holds (loopsHeld)
};

using PoseMap = std::map<core::PoseKey, Eigen::Isometry3d>;

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

}  // namespace detail

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
  /// Per own keyframe, the descriptor distance to the closest place like it
  /// elsewhere on the own route, before or after it (1: none known yet).
  std::vector<float> own_alike;
  std::map<std::string, double> counters;
  double now = 0.0;
  /// The keyframe count each robot heard announced last (heartbeats), and
  /// when one last grew (peersMappedAt).
  std::map<core::RobotId, std::uint32_t> announced_keyframes;
  double peers_mapped_at = detail::kNever;
  // Optimisation rounds.
  std::map<core::RobotId, detail::Link> links;
  std::optional<detail::Round> round;
  std::set<std::uint32_t> finished;  ///< rounds this robot took part in and left
  /// Of those, the rounds it left before they were done (abandoned, or ended
  /// early): a member still in one is told so when it is heard from.
  std::set<std::uint32_t> abandoned;
  std::uint32_t rounds_started = 0;
  double last_round_start = detail::kNever;  ///< when this robot last joined a round
  double last_announce = detail::kNever;
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
  detail::PoseMap anchors;
  std::set<backend::LoopId> anchored_loops;
  /// The own intra-robot loops when the estimates were last solved.
  std::size_t solved_own_loops = 0;
  double last_solved_alone = detail::kNever;

  Impl(comm::Transport& transport, const RobotConfig& c, std::uint32_t incarnation,
       std::unique_ptr<odometry::Odometry> front_end);

  void count(const std::string& name, double amount = 1.0) { counters[name] += amount; }

  // robot_node.cpp: the messages of a tick, to their stages.
  void tick(double time);
  void handle(const comm::Message& m);

  // keyframes.cpp: own scans and keyframes.
  void addScan(double stamp, const core::PointCloud& scan,
               const std::optional<Eigen::Vector3d>& up);
  void onKeyframe(const core::Keyframe& keyframe);
  [[nodiscard]] place::KeyframePosition ownPosition() const;

  // place_exchange.cpp: descriptors received, candidates sent (stages 1 and 2).
  Neighbour& neighbour(core::RobotId robot);
  void addOwnChain(backend::PairwiseConsistency& pcm) const;
  void onDescriptor(core::RobotId from, const comm::DescriptorMessage& d);
  [[nodiscard]] bool askedNearby(const Neighbour& n, core::KeyframeId own,
                                 core::KeyframeId theirs) const;
  void sendCandidate(core::RobotId to, core::KeyframeId own, core::KeyframeId theirs,
                     const place::Match& match);

  // loop_verification.cpp: candidates verified, measurements received (stages 2 and 3).
  void onCandidate(core::RobotId from, const comm::LoopCandidate& c);
  comm::LoopMeasurement verify(const comm::LoopCandidate& c);
  static backend::Factor loopFactor(core::RobotId verifier, core::RobotId querier,
                                    const comm::LoopMeasurement& m);
  void onMeasurement(core::RobotId from, const comm::LoopMeasurement& m);

  // loop_acceptance.cpp: PCM of each pair; loops withdrawn at repeated places
  // and after a round that cannot explain them.
  void addLoop(core::RobotId other, const backend::Factor& f);
  void decide(Neighbour& n);
  void redecideIfRejecting(Neighbour& n);
  void recountPcm();
  void judgeOwnRepeat(core::RobotId robot, Neighbour& n, const comm::Resemblance& earlier,
                      const place::PlaceDescriptor& later);
  void judgeTheirRepeat(core::RobotId robot, Neighbour& n, const comm::Resemblance& earlier,
                        const place::PlaceDescriptor& later);
  void judgeRepeat(core::RobotId robot, Neighbour& n,
                   const std::pair<core::KeyframeId, core::KeyframeId>& pair, double distance,
                   double repeat);
  void onRepeated(core::RobotId from, const comm::LoopMeasurement& m);
  void checkRoundLoops(const detail::PoseMap& own, const detail::PoseMap& members);
  void onUnexplained(core::RobotId from, const comm::LoopMeasurement& m);
  void withdrawIfBothSaw(core::RobotId partner, Neighbour& n, std::uint32_t round_number);

  // dgs_rounds.cpp: groups, and the DGS rounds they start, join and leave.
  [[nodiscard]] std::set<core::RobotId> loopNeighbours() const;
  [[nodiscard]] std::uint32_t loopsHeld() const;
  void announce();
  void onAnnouncement(core::RobotId from, const comm::DgsState& state);
  [[nodiscard]] std::set<core::RobotId> group() const;
  [[nodiscard]] bool grewByHalf(
      const std::vector<std::pair<core::RobotId, std::uint32_t>>& current) const;
  [[nodiscard]] std::vector<std::pair<core::RobotId, std::uint32_t>> signature(
      const std::set<core::RobotId>& members) const;
  void maybeStartRound();
  [[nodiscard]] backend::PoseGraph roundGraph(const std::set<core::RobotId>& members,
                                              const RoundOrigin& origin);
  void join(std::uint32_t number, const std::set<core::RobotId>& members,
            const RoundOrigin& origin);
  void leave(const char* why, bool soon = false);
  void onDgs(const backend::DgsMessage& m, const RoundOrigin& origin);
  void sendDgs(const backend::DgsMessage& m);
  void stepRound();
  [[nodiscard]] bool membersInStep();
  void resendDgsStep();
  void tellAbandoned(std::optional<core::RobotId> to, std::uint32_t number);
  void onAbort(core::RobotId from, std::uint32_t number);

  // round_refinement.cpp: the distributed refinement within a round.
  void startRefinement();
  void onRefine(const RefineMessage& m);
  void answerLateMember(const RefineMessage& m);
  void tellDgsMemberLeft(core::RobotId member);
  void send(RefineMessage m);
  void sendValues();
  bool takeValues(const std::set<core::RobotId>& robots);
  void advanceRefinement();
  void nextStep(detail::Refinement& r);
  void resendWhenStalled();
  void endRefinementEarly(const char* why);
  void stopRefinement();

  // estimates.cpp: the own estimates and the frame they are in.
  [[nodiscard]] Eigen::Isometry3d estimate(core::KeyframeId k) const;
  [[nodiscard]] backend::PoseGraph ownGraph() const;
  void finishRound(const detail::PoseMap& estimates, bool capped = false);
  void forgetFrameIfUnlinked();
  void maybeSolveAlone();
  std::size_t addHeldLoops(backend::PoseGraph& g, const std::set<core::RobotId>& members) const;
};

}  // namespace dcl::robot
