#pragma once

/// Distributed pose-graph optimisation by two-stage distributed Gauss-Seidel
/// (paper §III-C, Algorithm 1; Choudhary et al., "Distributed mapping with
/// privacy and communication constraints", IJRR 2017).
///
/// No transport inside: a DgsAgent per robot holds its local graph (its own
/// poses, its odometry and intra-robot loops, and the inter-robot loops that
/// touch it), hands out the separator values its neighbours need
/// (DgsAgent::outgoing), takes in theirs (DgsAgent::receive), and advances one
/// Gauss-Seidel step at a time (DgsAgent::iterate). runDgs() drives N agents
/// in one process by passing those values around: the same loop a robot node
/// runs over the radio.
///
/// The two stages, for a factor i -> j measuring (R_ij, t_ij) with isotropic
/// weights w_R and w_t (a third of the trace of the information's rotation and
/// translation blocks, as the paper's code weighs the chordal relaxation):
/// - Stage 1 (Carlone et al. 2015, "Initialization techniques for 3D SLAM"):
///   the chordal relaxation, min sum w_R |R_j - R_i R_ij|_F^2 over unconstrained
///   3x3 matrices, a linear least-squares problem whose three right-hand sides
///   (the rows of R) share one matrix; then each estimate is projected to SO(3)
///   (R^_i).
/// - Stage 2: the pose problem linearised at (R^, t = 0), Choudhary et al.'s
///   6-DoF correction. At t = 0 the translation and rotation parts decouple:
///   rotation corrections R_i = exp(d_i) R^_i from the residuals
///   d_j - d_i - log(R^_i R_ij R^_j^T) (weight w_R; the log's Jacobian taken as
///   the identity), then translations from t_j - t_i - R_i t_ij (weight w_t), with
///   R_i the corrected rotations. Both matrices are weighted graph Laplacians.
/// The cross terms of the information (rotation-translation) do not enter.
///
/// In both stages a robot's block matrix depends only on its own factors and on
/// which separators are in use, not on the neighbours' values: it is factored
/// (sparse Cholesky) at the robot's first step of a stage and again only when
/// more neighbours have initialised (flagged initialisation; in Algorithm 1's
/// order that is once more, at the second step); every other step only solves
/// (stage 1: one matrix, three right-hand sides; stage 2: two Laplacians).
///
/// Stage-2 messages carry the sender's current full separator poses
/// (exp(d) R^, t), and with its first one the separators' R^: the receiver
/// recovers d = log(R R^^T) and sets up exactly the centralized equations, so
/// DGS converges to chordalInitialise's estimate. Robots need not leave stage 1
/// at the same step (each sends its own R^ once it has it).
///
/// Stopping: a robot's step is converged when it changed its estimate by less
/// than the threshold (Euclidean norm over all its nodes: matrix entries in
/// stage 1, [t; d] in stage 2, as the paper's code) and it had already solved
/// with every neighbour of the group in use. Messages gossip each robot's
/// progress (DgsProgress), so every robot learns, within the group's diameter
/// in steps, of a step at which the whole group was converged, and leaves the
/// stage then. A robot with neither an anchor nor an initialised neighbour
/// waits (flagged initialisation: a neighbour's estimate is used only once
/// that neighbour has solved its block in the stage).

#include <Eigen/Geometry>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <map>
#include <memory>
#include <set>
#include <vector>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/config.hpp>
#include <dcl/core/ids.hpp>
#include <dcl/core/se3.hpp>

namespace dcl::backend {

/// How DGS runs (defaults from the paper's code).
struct DgsConfig {
  double gamma = 1.0;               ///< successive over-relaxation factor (1: plain Gauss-Seidel)
  double rotation_threshold = 0.1;  ///< stop stage 1 when no robot's estimate changes more
  double pose_threshold = 0.1;      ///< stop stage 2 when no robot's estimate changes more
  int max_rotation_iterations = 1000;  ///< stage 1 cap (steps of each robot)
  int max_pose_iterations = 1000;      ///< stage 2 cap
  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    // Over-relaxed Gauss-Seidel converges on these problems for gamma in (0, 2).
    v.field("gamma", gamma, "successive over-relaxation factor (1: Gauss-Seidel)")
        .within(0.0, 2.0, core::Interval::open);
    v.field("rotation_threshold", rotation_threshold, "stage 1 estimate-change threshold")
        .nonNegative();
    v.field("pose_threshold", pose_threshold, "stage 2 estimate-change threshold").nonNegative();
    v.field("max_rotation_iterations", max_rotation_iterations, "stage 1 iteration cap").positive();
    v.field("max_pose_iterations", max_pose_iterations, "stage 2 iteration cap").positive();
  }
};

/// Throws core::Error naming the first field that breaks its rule (visit()).
void validate(const DgsConfig& config);

/// Where an agent is in a round.
enum class DgsStage : std::uint8_t {
  idle,      ///< no round running
  rotation,  ///< stage 1
  pose,      ///< stage 2
  done,      ///< the round finished; estimates updated
};

/// What a robot knows of one group member's progress in a stage, relayed in
/// every message so that each robot can tell when the whole group, not only its
/// neighbours, has converged.
struct DgsProgress {
  int iteration = 0;  ///< the member's latest step heard of (steps counted in the round)
  int converged_since =
      -1;  ///< first step of its current run of converged steps; -1: not converged
  /// The member has left the stage (it saw the whole group converged, or hit
  /// the cap): the others follow at their next step.
  bool finished = false;
};

/// What a robot shares with one neighbour in one step: its current estimates
/// of the separators that neighbour's factors touch (rotations in stage 1,
/// poses in stage 2), and its flags.
struct DgsMessage {
  core::RobotId from;
  core::RobotId to;
  DgsStage stage = DgsStage::rotation;
  std::uint32_t round = 0;   ///< the round it belongs to (DgsAgent::startRound)
  int iteration = 0;         ///< the sender's step count in this round
  bool initialised = false;  ///< the sender has estimated its block once in this stage
  bool converged = false;    ///< the sender's last change was under the threshold
  /// Stage 1: the sender's (unprojected) chordal estimates; empty before it
  /// initialised. Stage 2, in the sender's first initialised message to this
  /// neighbour only: its projected stage-1 rotations R^, the point its poses
  /// are linearised at.
  std::map<core::PoseKey, Eigen::Matrix3d> rotations;
  /// Stage 2: the sender's current T_world_node; empty before it initialised.
  std::map<core::PoseKey, Eigen::Isometry3d> poses;
  std::map<core::RobotId, DgsProgress> progress;  ///< the sender's view of the group, this stage
};

/// One robot's optimiser.
///
/// A round: startRound() on every robot of a group, then repeatedly, robot by
/// robot in the group's order (optimisationOrder), iterate() and deliver
/// outgoing() to the neighbours (receive()), until every robot is done. A
/// robot's own stage decisions use only what it received.
class DgsAgent {
 public:
  /// The agent of robot `robot` over `local`: its own nodes (with their
  /// initial estimates, odometry-composed when unknown), every factor touching
  /// them (inter-robot ones name neighbours' nodes the graph need not hold).
  /// Nodes of `local` fixed and owned by `robot` stay fixed. A neighbour's
  /// node `local` holds and fixes is a held separator: in a round whose group
  /// leaves its robot out (a robot gone out of range) its value is a constant
  /// in use at every step, where a factor to an absent robot would otherwise
  /// be left out. Throws core::Error
  /// when the robot has no node, a factor's information is not finite or has a
  /// negative trace in a block, or the configuration is out of range.
  DgsAgent(core::RobotId robot, PoseGraph local, const DgsConfig& config = {});
  ~DgsAgent();
  DgsAgent(DgsAgent&&) noexcept;
  DgsAgent& operator=(DgsAgent&&) noexcept;

  /// Neighbours: robots an inter-robot factor of this agent connects to.
  [[nodiscard]] std::set<core::RobotId> neighbours() const;
  /// Own poses a neighbour's inter-robot factors touch, per neighbour.
  [[nodiscard]] const std::map<core::RobotId, std::set<core::PoseKey>>& separators() const;

  /// Starts a round with `group` (the robots connected to this one, itself
  /// included; the lowest id anchors the gauge: its lowest node is held fixed
  /// unless its local graph fixes one or it has a held separator). Factors to
  /// robots outside the group are left out of this round, but for held
  /// separators. Throws core::Error when the group does not hold this robot.
  void startRound(const std::set<core::RobotId>& group);
  /// The same with the round's number given (every robot of a round uses the
  /// same; the one-argument form counts up from the last).
  void startRound(const std::set<core::RobotId>& group, std::uint32_t round);
  /// Takes in a neighbour's message. Ignored when it is for another robot,
  /// round or an earlier stage, from outside the group, or older than the
  /// sender's last; dropped and counted (rejectedMessages) when malformed:
  /// non-finite or implausible values, a stage-2 rotation that is not one, or
  /// an inconsistent progress entry. A message from a neighbour still in a
  /// stage this robot has left (its last message of that stage, which says
  /// so, was lost) queues that last message again for it (replies()). Never
  /// throws.
  void receive(const DgsMessage& message) noexcept;
  /// The replies queued by receive() since the last call, handed over once.
  [[nodiscard]] std::vector<DgsMessage> replies();
  /// One Gauss-Seidel step of the current stage on this robot's block, with
  /// the neighbours' latest separator estimates fixed. Moves to the next
  /// stage when the group has converged (see DgsConfig) or hit the cap. A
  /// robot that cannot yet solve (neither anchor nor initialised neighbour)
  /// only counts the step. No-op when idle or done.
  void iterate();
  /// What to send each neighbour of the group after the last step (empty
  /// when the last iterate() did nothing).
  [[nodiscard]] std::vector<DgsMessage> outgoing() const;
  /// Abandons the round (a neighbour vanished): estimates revert to the last
  /// finished round's.
  void abortRound();

  [[nodiscard]] DgsStage stage() const;
  [[nodiscard]] core::RobotId robot() const;
  /// True when the robot has solved its block in the current stage.
  [[nodiscard]] bool initialised() const;
  /// Steps taken in the current round.
  [[nodiscard]] int iteration() const;
  /// Steps taken in stage 1 and stage 2 of the current (or last finished) round.
  [[nodiscard]] int stageIterations(DgsStage stage) const;
  /// Sparse Cholesky factorisations of block matrices since construction.
  [[nodiscard]] std::size_t factorizations() const;
  /// Messages dropped as malformed since construction.
  [[nodiscard]] std::size_t rejectedMessages() const;
  /// Current estimates T_world_node of the own nodes (the last finished round's while one runs).
  [[nodiscard]] const std::map<core::PoseKey, Eigen::Isometry3d>& estimates() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The local graphs of `graph` by robot (key.robot): each with the robot's
/// nodes (and which of them are fixed) and every factor touching one of them.
std::map<core::RobotId, PoseGraph> partitionByRobot(const PoseGraph& graph);

/// A single-robot graph split into `robots` robots by contiguous ranges of
/// its node order (as the distributed-mapper benchmarks split them; robot r
/// gets nodes [r n / robots, (r + 1) n / robots)); the nodes are re-keyed
/// (robot r, keyframe index within its range), factors between ranges become
/// inter-robot loops, consecutive keyframes of a range odometry, others
/// intra-robot loops. Throws core::Error when robots is not in
/// 1..min(255, nodes) or a factor names a node the graph does not hold.
PoseGraph splitIntoRobots(const PoseGraph& graph, int robots);

/// The robots owning nodes of `graph` (but those in `exclude`), grouped by
/// the inter-robot factors between them: each group connected, groups in
/// order of their lowest robot.
std::vector<std::set<core::RobotId>> connectedGroups(const PoseGraph& graph,
                                                     const std::set<core::RobotId>& exclude = {});

/// Algorithm 1's optimisation order of `group`: its lowest robot (the anchor)
/// first, then greedily the robot with the most inter-robot factors to the
/// robots already ordered (ties: the lower id), so each robot after the first
/// has an initialised neighbour when its turn comes.
std::vector<core::RobotId> optimisationOrder(const PoseGraph& graph,
                                             const std::set<core::RobotId>& group);

/// The centralized two-stage initialisation (Carlone et al. 2015): the same
/// rotation and pose stages solved on the whole graph at once (one block),
/// written into `graph`'s estimates. Fixed nodes hold the gauge; a connected
/// component without one is held by its lowest node. Factors naming a node
/// the graph does not hold are skipped. The reference solver starts from it.
/// Throws core::Error as DgsAgent does for a bad information matrix.
void chordalInitialise(PoseGraph& graph);

/// What a distributed solve did.
struct DgsSummary {
  /// Stage 1 rounds over the robots (sweeps of the groups' orders in which a
  /// robot was in stage 1; abandoned rounds' count too).
  int iterations_rotation = 0;
  int iterations_pose = 0;                    ///< stage 2 rounds, likewise
  std::size_t messages = 0;                   ///< DgsMessages exchanged
  std::size_t separator_values_rotation = 0;  ///< separator rotations sent, all robots and steps
  std::size_t separator_values_pose = 0;      ///< separator poses sent
  std::map<core::RobotId, std::size_t> values_sent;  ///< per robot, both stages
  std::size_t groups = 0;                            ///< connected groups that finished a round
  std::size_t aborted_rounds = 0;  ///< rounds abandoned because a robot stopped answering
  double seconds = 0.0;
};

/// Every message the robots of runDgs hand each other, as they hand it: for a
/// caller that measures it on the wire.
using DgsTraffic = std::function<void(const DgsMessage& message)>;

/// Runs DGS over every robot of `graph` in one process, in Algorithm 1's
/// order, and writes the estimates back into `graph`. Robots in `vanish`
/// stop answering after `vanish_after` stage-1 steps (for tests of a robot
/// leaving mid-round): the rest of its group notices the silence after that
/// sweep, abandons the round and starts a new one among the robots still
/// connected without it; the silent robot keeps its estimates. Groups run side
/// by side, one sweep of each per sweep. `traffic`, when set, sees every
/// message sent. Throws core::Error for a bad configuration or information
/// matrix.
DgsSummary runDgs(PoseGraph& graph, const DgsConfig& config = {},
                  const std::set<core::RobotId>& vanish = {}, int vanish_after = 0,
                  const DgsTraffic& traffic = {});

}  // namespace dcl::backend
