#pragma once

/// Distributed nonlinear refinement of a multi-robot pose graph, meant to run
/// after DGS (dgs.hpp). DGS solves a linearised problem (rotations by the
/// chordal relaxation, then poses linearised at them), so its answer lies near
/// the optimum of the nonlinear cost, not at it. Block-coordinate descent on the
/// nonlinear cost itself closes that gap: each robot in turn minimises the
/// cost of its own block (its poses free, the neighbours' separator poses its
/// inter-robot factors touch held at their latest shared values) by
/// Levenberg-Marquardt on SE(3), the same cost and parameterisation as the
/// centralized reference (centralized_solver.hpp), then shares its separators.
///
/// Gauss-Seidel, not Jacobi: robots step one after another in id order and
/// each uses the values its neighbours sent earlier in the same round, so a
/// correction crosses several robots in one round. A block step can only
/// lower the block's cost, and the rest of the graph's cost does not depend on
/// the block's poses, so a round never increases the whole graph's cost.
///
/// Plain block-coordinate descent crawls once the remaining error is spread
/// over several robots (smallGrid3D in 2 robots: the gap to the optimum
/// shrinks by about 1 % a round). Each round therefore starts from a
/// Nesterov extrapolation of the last two rounds (every pose moved along its
/// own geodesic, the momentum from Nesterov's sequence), with adaptive
/// restart as in accelerated Riemannian block-coordinate descent (Tian et al.,
/// "Distributed certifiably correct pose-graph optimization", T-RO 2021): a
/// round that ends above the previous round's cost is undone and run again
/// without momentum. The kept cost thus still never increases.
///
/// No transport inside, as in dgs.hpp: a RefineAgent per robot takes in its
/// neighbours' separator poses (RefineAgent::receive) and hands out its own
/// (RefineAgent::step); every robot extrapolates its neighbours' separators
/// itself from the values it already holds, so momentum costs no extra
/// message. refineDistributed() drives one agent per robot in one process by
/// passing those values around; the only global quantity it uses is the
/// graph's cost, the sum of one number per robot.

#include <Eigen/Geometry>
#include <cstddef>
#include <map>
#include <memory>
#include <set>
#include <vector>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/ids.hpp>

namespace dcl::backend {

/// How the refinement runs.
struct RefineConfig {
  /// Rounds at most (a round: every robot steps once and sends its separators).
  int max_rounds = 500;
  /// Stop when the graph's cost falls relatively less than this per round, on
  /// average over the last `window` rounds. Far below the 1e-3 the result is
  /// meant to reach: a round of block-coordinate descent gains little even where
  /// the optimum is still some way off.
  double relative_tolerance = 1e-6;
  /// Rounds the tolerance is averaged over: with momentum the gain of single
  /// rounds is uneven (example_25robots after DGS: 3e-7 in round 46, 7e-6 in
  /// round 60), and one poor round must not end the refinement.
  int window = 10;
  /// Levenberg-Marquardt iterations per block step: a block need not be solved
  /// exactly while its neighbours still move (one Gauss-Newton step a round
  /// takes as few rounds as ten on every benchmark graph). A robot without
  /// inter-robot factors solves its block to convergence instead.
  int block_iterations = 1;
  /// Relative cost decrease below which a block step stops.
  double block_tolerance = 1e-10;
  /// Steps a block's factorised normal equations may serve after the one
  /// they were made for (0: factorise for every step). The curvature of a
  /// block changes little between rounds, and factorising is most of a step.
  int factorisation_reuse = 8;
  /// Nesterov momentum with adaptive restart; false: plain block-coordinate descent.
  bool accelerate = true;

  /// Lists the fields for the YAML loader (io/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("max_rounds", max_rounds, "rounds over all robots at most");
    v.field("relative_tolerance", relative_tolerance,
            "stop below this relative cost decrease per round");
    v.field("window", window, "rounds the tolerance is averaged over");
    v.field("block_iterations", block_iterations, "Levenberg-Marquardt iterations per block step");
    v.field("block_tolerance", block_tolerance, "relative function tolerance within a block step");
    v.field("factorisation_reuse", factorisation_reuse,
            "steps a block's factorisation may serve after its first");
    v.field("accelerate", accelerate, "Nesterov momentum with adaptive restart");
  }
};

/// Throws core::Error naming the first field out of range.
void validate(const RefineConfig& config);

/// What one robot's step did and what it sends.
struct RefineStep {
  /// Per neighbour, the new estimates of the own poses that neighbour's factors touch.
  std::map<core::RobotId, std::map<core::PoseKey, Eigen::Isometry3d>> outgoing;
  double cost_before = 0.0;  ///< chi-square of the block's factors at the round's start point
  double cost_after = 0.0;   ///< and after the step (never more than before)
  int iterations = 0;        ///< Levenberg-Marquardt iterations run
};

/// One robot's share of the refinement. A round, for every agent:
/// beginRound(), then receive() whatever neighbours send (before or after this
/// agent's step), step() once in turn, and endRound() when every robot has
/// stepped, with the group's verdict on the round.
class RefineAgent {
 public:
  /// The agent of robot `robot` over `local`: its own nodes (key.robot ==
  /// robot) with their estimates, and the factors touching them. Nodes of
  /// other robots in `local` are the first values of the neighbours'
  /// separators; a factor to a neighbour pose with no value yet waits for one.
  /// A neighbour's node fixed in `local` is held where it is: a neighbour out
  /// of the group, where an earlier round left it. Nothing is sent for it or
  /// taken in, and this agent owns the factors to it (ownedCost).
  /// Own nodes fixed in `local` stay fixed; with none fixed and no inter-robot
  /// factor, the lowest own node a factor touches is (the block alone has a
  /// free gauge). Factors joining a node to itself are left out (a constant).
  /// Throws core::Error when the configuration is out of range.
  RefineAgent(core::RobotId robot, const PoseGraph& local, const RefineConfig& config = {});
  ~RefineAgent();
  RefineAgent(RefineAgent&&) noexcept;
  RefineAgent& operator=(RefineAgent&&) noexcept;

  [[nodiscard]] core::RobotId robot() const;
  /// Robots an inter-robot factor of this agent connects to.
  [[nodiscard]] std::set<core::RobotId> neighbours() const;
  /// Own poses each neighbour's factors touch: what this agent sends.
  [[nodiscard]] const std::map<core::RobotId, std::set<core::PoseKey>>& separators() const;
  /// Neighbours' poses this agent's factors touch: what it needs.
  [[nodiscard]] const std::set<core::PoseKey>& neighbourPoses() const;

  /// Starts a round from the last kept estimates extrapolated by `momentum`
  /// (0: from them as they are): own poses and the neighbours' separators alike,
  /// T_prev exp((1 + momentum) log(T_prev^-1 T_last)) per pose.
  void beginRound(double momentum = 0.0);
  /// Takes in neighbours' separator poses sent in this round; others are ignored.
  void receive(const std::map<core::PoseKey, Eigen::Isometry3d>& neighbour_poses);
  /// This round's block step: minimises the block's cost with the neighbours'
  /// latest values fixed; returns what to send each neighbour.
  RefineStep step();
  /// Ends the round: `keep` makes its estimates and the values received in it
  /// the kept ones; otherwise both revert to the last kept ones (the round overshot).
  void endRound(bool keep);

  /// Current estimates T_world_node of the own nodes (this round's after step()).
  [[nodiscard]] const std::map<core::PoseKey, Eigen::Isometry3d>& estimates() const;
  /// The neighbours' separator poses as of the last kept round.
  [[nodiscard]] const std::map<core::PoseKey, Eigen::Isometry3d>& neighbourValues() const;

  /// This robot's share of the graph's cost: the chi-square of the factors it
  /// owns (both ends its own, an inter-robot factor whose other robot has a
  /// higher id, or one to a held neighbour pose) at its current estimates and
  /// the neighbours' latest values.
  /// Every factor has exactly one owner, so the shares of a group's robots sum
  /// to the whole graph's cost: all a group needs to share for RefineSchedule.
  [[nodiscard]] double ownedCost() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// The group-wide decisions of a refinement, made alike by every robot from
/// the same sequence of whole-graph costs: the momentum of the next round,
/// whether a round is kept or undone (adaptive restart), and when to stop
/// (the relative tolerance over the window, or max_rounds).
class RefineSchedule {
 public:
  /// Starts at the graph's cost before the first round.
  RefineSchedule(const RefineConfig& config, double initial_cost);

  /// The momentum the next round starts with (RefineAgent::beginRound).
  [[nodiscard]] double momentum() const;
  /// Ends a round whose graph cost came to `cost`; returns whether it is kept
  /// (RefineAgent::endRound).
  bool endRound(double cost);
  /// The refinement has converged or used its rounds.
  [[nodiscard]] bool done() const;
  [[nodiscard]] bool converged() const { return converged_; }
  [[nodiscard]] int rounds() const { return rounds_; }
  [[nodiscard]] int restarts() const { return restarts_; }
  /// The kept cost: the initial one, then the last kept round's.
  [[nodiscard]] double cost() const { return kept_costs_.back(); }
  /// The kept cost after each round, never increasing.
  [[nodiscard]] const std::vector<double>& roundCosts() const { return round_costs_; }

 private:
  RefineConfig config_;
  double t_ = 1.0;  ///< Nesterov's sequence; 1: no momentum
  std::vector<double> kept_costs_;
  std::vector<double> round_costs_;
  int rounds_ = 0;
  int restarts_ = 0;
  bool converged_ = false;
};

/// What a refinement did. Costs are g2o's chi-square of the whole graph (graphCost).
struct RefineSummary {
  int rounds = 0;                    ///< rounds run (restarted ones included)
  int restarts = 0;                  ///< rounds undone because the momentum overshot
  double initial_cost = 0.0;         ///< before
  double final_cost = 0.0;           ///< after
  std::vector<double> round_costs;   ///< the kept cost after each round, never increasing
  std::size_t separator_values = 0;  ///< separator poses sent, all robots and rounds
  std::map<core::RobotId, std::size_t> values_sent;  ///< separator poses sent, per robot
  double seconds = 0.0;                              ///< wall time
  bool converged = false;  ///< the rounds gained less than the tolerance before max_rounds
};

/// Refines every estimate of `graph` in place by Gauss-Seidel block-coordinate
/// descent over its robots (key.robot), robots in id order, one agent each,
/// from its current estimates (DGS's result, or any other).
/// The gauge: the graph's fixed nodes stay fixed; with none, its lowest node
/// (the lowest robot's first) does, as in solveCentralized. Factors naming a
/// node the graph does not hold are skipped. Throws core::Error when the
/// configuration is out of range.
RefineSummary refineDistributed(PoseGraph& graph, const RefineConfig& config = {});

}  // namespace dcl::backend
