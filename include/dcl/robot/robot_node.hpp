#pragma once

/// One robot's whole life (paper Fig. 5, Algorithm 1) as a single-threaded
/// event handler: scans in, messages in and out through a Transport, nothing
/// else. The same node runs N times in one process over the simulated radio
/// and once per process over Cyclone DDS.
///
/// Per scan: odometry, keyframe selection, intra-robot loops (LocalMapper).
/// Per new keyframe: its LiDAR-Iris descriptor goes into the own place index
/// and, with the odometry step that led to it, to every neighbour (stage 1;
/// the Messenger re-sends it to neighbours met later). Per descriptor
/// received: the neighbour's odometry chain grows, and the own index is
/// searched; a match becomes a candidate sent, with the compact cloud of the
/// own keyframe, to the robot that owns the matched place (stage 2). Per
/// candidate received: verification against the own submap around the
/// matched keyframe, and the answer back (stage 3). A verified loop, on
/// either side, goes to the PCM of that robot pair; both robots of a pair
/// hold the same loops and the same odometry chains, so both keep the same
/// consistent set. The node never waits: a silent neighbour simply sends
/// nothing, and one that returns is caught up by the Messenger.
///
/// Optimisation (Algorithm 1). Every robot announces, every few seconds, the
/// robots it shares accepted loops with and how many; from the announcements
/// of the robots in range each robot knows the connected group it belongs to.
/// The lowest robot of a group starts a DGS round (backend::DgsAgent, every
/// exchange through comm's messages) whenever the group's loops changed since
/// its last round; the others join when its first message reaches them. The
/// anchor's first pose stays where it is, so every member ends in the
/// anchor's frame. DGS's answer solves a linearised problem; the round goes
/// on with the distributed refinement (backend::RefineAgent) from it: in each
/// step a robot solves its block once its lower-id neighbours have sent their
/// separators of that step, sends its own, and shares its part of the graph's
/// cost; every member takes the same keep, restart and stop decisions
/// (backend::RefineSchedule) from the same shares. A refinement message lost
/// is sent again while the robot waits. A round abandoned in DGS (a member
/// out of range, a timeout) changes nothing; one cut short in its refinement,
/// or still settling when the robot stops, keeps the last step the group
/// kept. A robot alone keeps its own frame. Keyframes added after a round
/// follow the last optimised one by odometry.
///
/// Every decision is counted (RobotNode::counters), so a user can see why no
/// loop was found: descriptors sent and received, candidates, verifications
/// passed and refused by reason, loops PCM kept and rejected, optimisation
/// rounds finished and abandoned.

#include <Eigen/Geometry>
#include <cstdint>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <vector>

#include <dcl/backend/dgs.hpp>
#include <dcl/backend/distributed_refine.hpp>
#include <dcl/backend/loop_check.hpp>
#include <dcl/backend/pcm.hpp>
#include <dcl/backend/pose_graph.hpp>
#include <dcl/comm/messenger.hpp>
#include <dcl/comm/transport.hpp>
#include <dcl/core/ids.hpp>
#include <dcl/core/keyframe.hpp>
#include <dcl/core/point_cloud.hpp>
#include <dcl/odometry/lidar_odometry.hpp>
#include <dcl/odometry/local_mapper.hpp>
#include <dcl/odometry/odometry.hpp>
#include <dcl/place/descriptor.hpp>
#include <dcl/place/place_index.hpp>
#include <dcl/registration/cloud_codec.hpp>
#include <dcl/registration/verification.hpp>

namespace dcl::robot {

/// Everything a robot node is configured with: the modules' own sections.
struct RobotConfig {
  odometry::OdometryConfig odometry;              ///< the built-in LiDAR odometry
  odometry::LocalMapperConfig mapper;             ///< keyframes, intra-robot loops
  place::DescriptorConfig descriptor;             ///< must be LiDAR-Iris (the wire codec's)
  place::PlaceIndexConfig index;                  ///< candidates and match threshold
  registration::VerificationConfig verification;  ///< stage 2 verification and its cloud
  /// PCM of each robot pair. Its `intra_loops` is not used: a neighbour only
  /// knows this robot's odometry chain, and both robots must check loops
  /// against the same trajectories to decide alike.
  backend::PcmConfig pcm;
  /// After each round, the loops to its members its solution cannot explain
  /// (the second line of defence after PCM; backend/loop_check.hpp).
  backend::LoopCheckConfig loop_check;
  comm::MessengerConfig messenger;  ///< heartbeats, neighbours, retransmission
  /// The distributed optimisation's stages, at most 100 steps each in a
  /// round (the refinement goes on from wherever DGS stopped).
  backend::DgsConfig dgs = [] {
    backend::DgsConfig c;
    c.max_rotation_iterations = 100;
    c.max_pose_iterations = 100;
    return c;
  }();
  /// The distributed refinement after DGS in every round (max_rounds 0: DGS
  /// alone). Fewer rounds than an offline refinement: rounds repeat as loops
  /// arrive, and each refinement round costs the group a message chain. A
  /// round that ends on this cap, not converged, is followed by a warm round
  /// that goes on from its estimate, so the cap spreads a long refinement
  /// over rounds rather than cutting it short.
  backend::RefineConfig refine = [] {
    backend::RefineConfig c;
    c.max_rounds = 200;
    return c;
  }();
  /// Keyframes between the own keyframes of two candidates to one neighbour
  /// at least (1: every match), once the pair holds pcm.min_loops accepted
  /// loops: loops a few metres apart add little to the graph but their
  /// clouds, their verification and their separators.
  std::uint64_t candidate_spacing = 3;
  /// Noise added to every verified loop's covariance (standard deviations, m
  /// and rad): the registration's own covariance sees only how well the two
  /// clouds constrain each other, not the errors of the submap it aligned to,
  /// and a loop trusted to micrometres bends the odometry around it.
  double loop_sigma_translation = 0.02;
  double loop_sigma_rotation = 0.0035;  ///< 0.2 deg
  /// Noise about the keyframe's x and y axes instead, when larger (rad). A
  /// loop's roll and pitch tie two robots' attitudes at one place, where each
  /// robot's attitude errs by its own sensor; the odometry gives way in roll
  /// and pitch, its loosest directions, and bends the partner's height along
  /// its route. At 0.2 rad the loops tie position and heading only (as the
  /// 4-DoF loops of visual-inertial systems do) and each robot keeps its own
  /// roll and pitch: over four simulated worlds of each preset that helps the
  /// three-robot swarms, not the nine-robot campus, and the robots' maps
  /// agree less well in tilt (BENCHMARKS.md, "Across worlds"). 0: as
  /// loop_sigma_rotation.
  double loop_sigma_tilt = 0.0;
  /// s from the start of one optimisation round to the start of the next, at
  /// least: a group optimises at most once a period, however fast its
  /// messages travel. (Counted from a round's end, a swarm over DDS, whose
  /// rounds take a second where the simulated radio's take eight, ran twice
  /// as many rounds and sent twice the bytes.) Only an announce_period when
  /// the group's loops grew by half since its last round: a new pair's first
  /// round, on a handful of loops, is redone while the robots are in range.
  double optimise_period = 20.0;
  /// s a round may go without a step (DGS or refinement) before it is given
  /// up: a member stopped answering. A round that keeps stepping is not cut.
  double round_timeout = 30.0;
  /// s between announcements of this robot's loop neighbours (how groups form).
  double announce_period = 2.0;
  /// A robot with no one in range to optimise with, whose loops changed since
  /// its estimates were last solved, solves its own graph (odometry, its own
  /// loops, and the accepted loops to the neighbours of its last round, their
  /// poses held where that round left them) at most once an optimise_period.
  /// Without it, loops closed after a robot's last round never reach the
  /// keyframes that round placed.
  bool solve_alone = true;
  /// In a round (DGS and its refinement), hold the accepted loops to
  /// neighbours out of the group (out of range, or gone) where the last
  /// rounds left those neighbours (a round in another frame takes them along
  /// with this robot's keyframes): what the round moves stays where they
  /// placed their maps, which they cannot hear of. Held poses are constants
  /// that anchor the round's gauge: a member holding some pins none of its
  /// own poses. Without it a round optimises its members' loops only, its
  /// lowest member's first pose pinned, and the swarm's maps part where the
  /// absent robots met it.
  bool hold_absent = true;
};

/// An inter-robot loop this robot knows of, and what became of it.
struct InterLoop {
  backend::Factor factor;  ///< from the verifying robot's keyframe to the querying robot's
  bool accepted = false;   ///< in PCM's current consistent set
};

class RobotNode {
 public:
  /// Robot `transport.self()` in its life `incarnation` (> 0). Throws
  /// core::Error for an invalid configuration (or a descriptor other than
  /// LiDAR-Iris, the only one with a wire codec).
  RobotNode(comm::Transport& transport, const RobotConfig& config, std::uint32_t incarnation = 1);
  /// The same with another front-end than the built-in LiDAR odometry (an
  /// external one: the poses of the robot's own LiDAR-inertial odometry).
  RobotNode(comm::Transport& transport, const RobotConfig& config, std::uint32_t incarnation,
            std::unique_ptr<odometry::Odometry> front_end);
  ~RobotNode();
  RobotNode(const RobotNode&) = delete;
  RobotNode& operator=(const RobotNode&) = delete;

  [[nodiscard]] core::RobotId id() const;

  /// A scan taken at `stamp` (s, the robot's clock), through the front-end,
  /// with the robot's IMU reading of up then when it has one
  /// (odometry::Odometry::observeUp).
  void addScan(double stamp, const core::PointCloud& scan,
               const std::optional<Eigen::Vector3d>& up = std::nullopt);

  /// Handles what arrived and runs the timers at `now` (s, non-decreasing).
  void tick(double now);

  /// Keyframes so far (clouds included).
  [[nodiscard]] const std::vector<core::Keyframe>& keyframes() const;
  /// The own pose graph: odometry and intra-robot loops (LocalMapper).
  [[nodiscard]] const backend::PoseGraph& localGraph() const;
  /// Every inter-robot loop known, with PCM's current verdict.
  [[nodiscard]] std::vector<InterLoop> interLoops() const;
  /// The local graph with the accepted inter-robot loops and the neighbours'
  /// keyframes they reach, each where its first loop puts it from this robot's
  /// keyframe; the own estimates are the latest (estimate()).
  [[nodiscard]] backend::PoseGraph graph() const;
  /// Keyframe `k`'s pose T_world_keyframe in the frame of the robot's group
  /// (its own odometry frame until a round finished).
  [[nodiscard]] Eigen::Isometry3d estimate(core::KeyframeId k) const;
  /// The frame the estimates are in, named by the robot whose odometry frame
  /// it is (frames.hpp): the own until a round places the robot. None after
  /// a round whose frame its initiator did not say.
  [[nodiscard]] std::optional<core::RobotId> frame() const;

  /// The robot stops (its data played and the time to settle spent, or told
  /// to): a round whose refinement is settling (its cost fell by at most 2 %
  /// over its last 10 kept steps) ends with the last step the group kept, so
  /// the estimates are that round's rather than the last finished one's
  /// (`rounds_ended_by_stop`). A round still in DGS, or whose refinement is
  /// still repairing DGS's estimate, is left, and the robot keeps what it
  /// held (`dgs_rounds_left_at_stop`, `rounds_left_unsettled_at_stop`).
  /// Call it once, last; the node takes no scan or tick after it.
  void stop();

  /// Nothing left to optimise with the robots in range: no round under way,
  /// none due for changed loops, and the last one converged. A recording
  /// played to its end leaves its robots running until they all are.
  [[nodiscard]] bool settled() const;

  /// When (tick time) a robot heard last announced more keyframes in its
  /// heartbeat than before: a teammate still mapping, whose places this robot
  /// can still match. kNever (-infinity) if none has grown since it was heard
  /// first. A robot done with its own data lingers while its peers map.
  [[nodiscard]] double peersMappedAt() const;

  /// Every decision counted, by name (see the class comment).
  [[nodiscard]] const std::map<std::string, double>& counters() const;
  [[nodiscard]] const comm::Messenger& messenger() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Throws core::Error naming the first invalid field.
void validate(const RobotConfig& config);

/// The covariance a verified inter-robot loop is kept with: the
/// registration's, with the configured loop noise added
/// (RobotConfig::loop_sigma_translation, loop_sigma_rotation, loop_sigma_tilt).
core::Matrix6d loopCovariance(const core::Matrix6d& registration, const RobotConfig& config);

}  // namespace dcl::robot
