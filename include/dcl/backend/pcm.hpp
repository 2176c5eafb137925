#pragma once

/// Pairwise consistency maximisation (PCM, Mangelson et al. 2018) of the
/// inter-robot loop closures between two robots (paper §III-C, Eq. 8).
///
/// Two loops z_ik (a_i -> b_k) and z_jl (a_j -> b_l) are consistent when the
/// cycle they close with the two robots' own trajectories,
///   T = z_ik * T_{b_k b_l} * z_jl^-1 * T_{a_j a_i},
/// is the identity within its uncertainty: the squared Mahalanobis distance
/// of log(T), under the covariance propagated through the cycle from the four
/// parts' covariances, is at most a threshold (5.348, the median of
/// chi-square with 6 degrees of freedom, by default). The loops kept are the
/// maximum clique of the graph of consistent pairs (max_clique.hpp; among
/// several, the lexicographically smallest in loop-key order).
///
/// Approximations: first-order propagation with right perturbations
/// (T exp(xi), xi = [rho; phi]) and the log's Jacobian taken as the identity
/// (exact for a consistent cycle, which is near the identity); the relative
/// poses T_{a_j a_i} and T_{b_k b_l} are composed along one path of each
/// robot's odometry and intra-robot loops (pcm_trajectory.hpp), so their
/// covariance bounds the smoothed one from above and errs towards calling
/// loops consistent.
///
/// The decision of a pair is a function of its loops and of the two robots'
/// odometry and intra-robot loops only, not of the order they arrived in or of
/// which robot of the pair computes it: every loop is oriented from the lower
/// robot id, every pair of loops is evaluated in key order, the trajectory
/// trees depend on their factor sets alone, and the clique is the canonical
/// one. So each robot runs PCM with each neighbour and, holding the same
/// factors, both reach the same verdict without exchanging it.

#include <cstddef>
#include <cstdint>
#include <map>
#include <optional>
#include <set>
#include <utility>
#include <vector>

#include <dcl/backend/max_clique.hpp>
#include <dcl/backend/pcm_trajectory.hpp>
#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/ids.hpp>

namespace dcl::backend {

/// How PCM decides.
struct PcmConfig {
  /// Largest squared Mahalanobis distance of a consistent pair's cycle
  /// (5.348: median of chi-square(6), the paper's value).
  double threshold = 5.348;
  /// Loops of one robot pair beyond which the clique is the heuristic's.
  std::size_t max_exact_loops = 5000;
  /// Search nodes of the exact clique before it falls back to the heuristic
  /// (a count, so every robot falls back at the same point).
  std::size_t max_branch_nodes = 2'000'000;
  /// Compose a robot's relative poses through its intra-robot loops too (false:
  /// along its odometry chain alone, whose covariance grows with the time
  /// between the two keyframes and lets more wrong loops pass).
  bool intra_loops = true;
  /// The kept set is held back until it holds at least this many loops: a
  /// lone loop has nothing to be consistent with. Loops from neighbouring
  /// keyframes agree with each other whether they are right or wrong (a
  /// repeated block seen from three keyframes); what refutes such a cluster
  /// is the rest of the group's loops, after the round that solves them
  /// together (loop_check.hpp). So two robots that met once, at one place,
  /// merge their maps on a few agreeing loops there. 1: the paper's PCM.
  std::size_t min_loops = 2;

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("threshold", threshold,
            "largest squared Mahalanobis distance of a consistent loop pair (chi-square(6) median)")
        .positive();
    v.field("max_exact_loops", max_exact_loops,
            "loops of one robot pair beyond which the clique is heuristic");
    v.field("max_branch_nodes", max_branch_nodes,
            "exact clique search nodes before falling back to the heuristic");
    v.field("intra_loops", intra_loops,
            "compose relative poses through intra-robot loops (false: odometry chain only)");
    v.field("min_loops", min_loops,
            "fewest mutually consistent loops of a robot pair before they are kept (1: none held "
            "back)")
        .positive();
  }
};

/// The same measurement seen from its other end: T_to_from, with the
/// information carried over (Omega' = Ad(T)^-T Omega Ad(T)^-1).
Factor invertFactor(const Factor& factor);

/// Eq. 8: the squared Mahalanobis distance of the cycle closed by two loops
/// between robots a and b (each from a's keyframe to b's) and the two robots'
/// trajectories. Throws core::Error when a trajectory does not reach a keyframe.
double cycleDistance(const Factor& loop_1, const Factor& loop_2, const TrajectoryTree& robot_a,
                     const TrajectoryTree& robot_b);

/// What PCM decided for one robot pair. Loops are oriented from the lower robot
/// and listed in key order.
struct PcmDecision {
  std::vector<Factor> accepted;  ///< the maximum set of pairwise consistent loops
  std::vector<Factor> rejected;  ///< inconsistent with that set
  /// Loops not judged yet, so not accepted: their keyframes are beyond the
  /// trajectories held, or the consistent set has fewer than min_loops.
  std::vector<Factor> unverified;
  std::vector<Factor> withdrawn;  ///< taken out of the judgement (withdraw)
  bool too_few = false;           ///< the consistent set was held back: fewer than min_loops
  bool exact = true;  ///< the clique is the exact, canonical one (not the heuristic fallback)
  std::size_t consistent_pairs = 0;  ///< edges of the consistency graph
};

/// Incremental PCM between two robots. A new loop is checked against the loops
/// already held (O(n) cycle evaluations); the consistency graph is kept, and
/// decide() solves its clique again only when the new loops could change it.
/// New odometry at the end of a trajectory keeps the graph; a factor that
/// changes a trajectory's tree (an intra-robot loop, say) has every pair
/// checked again at the next decide().
class PairwiseConsistency {
 public:
  /// PCM between robots `a` and `b` (in either order; the lower is "a"), whose
  /// trajectories start at keyframe 0.
  PairwiseConsistency(core::RobotId a, core::RobotId b, const PcmConfig& config = {});

  /// PCM between the robots of two trajectories (in either order), which may
  /// hold factors already and start anywhere.
  PairwiseConsistency(TrajectoryTree a, TrajectoryTree b, const PcmConfig& config = {});

  /// Adds an odometry factor or intra-robot loop of either robot (see TrajectoryTree::add).
  void addRobotFactor(const Factor& factor);

  /// Adds a loop between the two robots (either orientation) and checks it
  /// against the loops held. Returns false, and ignores it, when a loop between
  /// the same two keyframes is held already. Throws core::Error for a factor
  /// that is not between these two robots.
  bool addLoop(const Factor& loop);

  /// Puts `loop` (either orientation) in place of the loop held between the
  /// same two keyframes, and checks every loop again (the next decide()).
  /// Returns false, and ignores it, when no such loop is held. Throws
  /// core::Error for a factor that is not between these two robots.
  bool replaceLoop(const Factor& loop);

  /// Takes the loop `id` out of the judgement for good (the group's solution
  /// cannot explain it, loop_check.hpp): it is never accepted, and the other
  /// loops are judged again without it. A loop withdrawn before it arrives
  /// stays out when it does. Returns false when it was withdrawn already.
  bool withdraw(const LoopId& id);

  /// The current decision (valid until the next add). Loops whose keyframes
  /// the trajectories did not reach when they were added are checked now if
  /// they reach them.
  const PcmDecision& decide();

  /// The loops held, oriented from the lower robot, in the order added.
  [[nodiscard]] std::vector<Factor> loops() const;

  /// The two robots, lower first.
  [[nodiscard]] std::pair<core::RobotId, core::RobotId> robots() const {
    return {robot_a_.robot(), robot_b_.robot()};
  }

 private:
  struct Candidate {
    Factor loop;                        ///< oriented from robot a
    core::Matrix6d covariance;          ///< of the measurement
    core::Matrix6d inverse_covariance;  ///< of its inverse, Ad(T) Sigma Ad(T)^T
    std::optional<std::size_t> vertex;  ///< in the consistency graph, once checked
  };
  /// `loop` oriented from robot a, unchecked; throws for a loop not between the two robots.
  Candidate candidateOf(const Factor& loop) const;
  bool reachable(const Factor& loop) const;
  void syncTrajectories();
  /// Forgets every consistency check (the loops stay): decide() checks them again.
  void resetChecks();
  void check(std::size_t index);
  double distance(const Candidate& first, const Candidate& second) const;
  std::vector<std::size_t> canonicalOrder() const;
  bool cliqueUnchanged() const;

  void solve();

  PcmConfig config_;
  TrajectoryTree robot_a_;
  TrajectoryTree robot_b_;
  std::pair<std::uint64_t, std::uint64_t> revisions_{0, 0};  ///< of the trees the graph used
  std::vector<Candidate> candidates_;
  std::map<LoopId, std::size_t> index_;
  std::set<LoopId> withdrawn_;  ///< out of the judgement (withdraw), whether held or not
  std::vector<std::size_t> vertex_candidate_;  ///< candidate of each graph vertex
  AdjacencyGraph graph_;
  std::size_t edges_ = 0;
  std::vector<bool> accepted_;  ///< per graph vertex, in the last decision
  PcmDecision decision_;
  bool decided_ = false;              ///< decision_ reflects every loop added
  std::size_t decided_vertices_ = 0;  ///< graph vertices when the clique was last solved
  std::size_t clique_size_ = 0;       ///< its size
};

/// PCM of one robot pair of a multi-robot graph.
struct PcmPairResult {
  core::RobotId robot_a;  ///< the lower robot
  core::RobotId robot_b;
  PcmDecision decision;
};

/// PCM of every robot pair of a multi-robot graph.
struct PcmResult {
  std::vector<PcmPairResult> pairs;  ///< by robot pair

  [[nodiscard]] std::size_t loops() const;     ///< inter-robot loops (distinct keys)
  [[nodiscard]] std::size_t accepted() const;  ///< loops kept
  /// The identities of the loops kept, in key order.
  [[nodiscard]] std::vector<LoopId> acceptedIds() const;
};

/// Runs PCM on every robot pair that shares inter-robot loops in `graph`, each
/// pair with the odometry factors and intra-robot loops of its two robots (each
/// trajectory tree rooted at the robot's lowest keyframe). A loop repeated with
/// the same keys counts once (the first in factor order).
PcmResult runPcm(const PoseGraph& graph, const PcmConfig& config = {});

}  // namespace dcl::backend
