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
/// Each kept round is followed by a coarse correction (refine_coarse.hpp):
/// a smooth deformation of every robot's part of the map, one Gauss-Newton
/// step for all robots at once on a coarse grid per robot, from small shares
/// every robot sends to the group. It moves what block steps move slowly (a
/// correction spanning several robots) and takes long, thin graphs (KITTI,
/// MIT, city10000) from hundreds of rounds to tens. The coarse step is
/// safeguarded like a line search: every robot prices it at a few lengths on
/// its own factors (kCoarseScales, four numbers to the group), the group
/// takes the cheapest that lowers the cost, and when even that falls short
/// of the coarse model's prediction every robot sends fresh blocks (the
/// blocks, refreshed only now and then, are what goes stale).
///
/// No transport inside, as in dgs.hpp: a RefineAgent per robot takes in its
/// neighbours' separator poses (RefineAgent::receive) and hands out its own
/// (RefineAgent::step); every robot extrapolates its neighbours' separators
/// itself from the values it already holds, so momentum costs no extra
/// message. refineDistributed() drives one agent per robot in one process by
/// passing those values around; the only global quantity it uses is the
/// graph's cost, the sum of one number per robot.

#include <Eigen/Geometry>
#include <array>
#include <cstddef>
#include <functional>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <vector>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/backend/refine_coarse.hpp>
#include <dcl/core/config.hpp>
#include <dcl/core/ids.hpp>

namespace dcl::backend {

/// How the refinement runs.
struct RefineConfig {
  /// Coarse cells along a robot's longest side at most: (64 + 1)^3 nodes of six
  /// unknowns is already more than a coarse level should hold.
  static constexpr int kMaxCoarseCells = 64;

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
  /// Cells of a robot's coarse grid along the longest side of its part of the
  /// map (0: no coarse correction). Four: city10000 in 4 robots reaches 1.001
  /// times its optimum in 9 rounds, eight in 6, at four times the shares'
  /// bytes. Eight: manhattan, whose robots each criss-cross the whole map,
  /// needs it (four leaves 4 robots at 1.0021 after 500 rounds; eight ends at
  /// 1.0004 after 276).
  int coarse_cells = 8;
  /// A robot sends its coarse Gauss-Newton blocks again when they changed by
  /// more than this fraction (Frobenius) since it last sent them; otherwise
  /// its shares carry the gradient only. The blocks change with the
  /// linearisation point, a lot while rotations still move (MIT) and hardly
  /// once the cost settles.
  double coarse_refresh = 0.1;
  /// Every robot sends fresh coarse blocks after a round whose coarse step,
  /// at its best priced length, lowered the cost by less than this fraction
  /// of what the coarse model predicted (0: only by coarse_refresh). A
  /// Frobenius change of 1 % in the blocks can turn the step from a descent
  /// into a rise of 50 % (manhattan in 9 robots): the change that matters is
  /// in the blocks' weakest directions, which the norm does not see.
  double coarse_trust = 0.5;
  /// A robot sends a separator pose only when it moved, from the value its
  /// neighbours already hold (their extrapolation and coarse step of it), by
  /// more than this fraction of the block's root-mean-square whitened
  /// residual, in some inter-robot factor on it: the change of that factor's
  /// whitened residual (0: every separator, every round). Each neighbour's
  /// copy stays within it of the sender's pose. 0.001 cuts city10000 in 4
  /// robots from 19.4 to 16.7 MB (ratio 1.00003), but leaves parking-garage
  /// in 9 robots at 1.00098 and rounds stop early on their copies' noise:
  /// off by default.
  double separator_tolerance = 0.0;

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("max_rounds", max_rounds, "rounds over all robots at most").nonNegative();
    v.field("relative_tolerance", relative_tolerance,
            "stop below this relative cost decrease per round")
        .nonNegative();
    v.field("window", window, "rounds the tolerance is averaged over").positive();
    v.field("block_iterations", block_iterations, "Levenberg-Marquardt iterations per block step")
        .positive();
    v.field("block_tolerance", block_tolerance, "relative function tolerance within a block step")
        .nonNegative();
    v.field("factorisation_reuse", factorisation_reuse,
            "steps a block's factorisation may serve after its first")
        .nonNegative();
    v.field("accelerate", accelerate, "Nesterov momentum with adaptive restart");
    v.field("coarse_cells", coarse_cells,
            "cells of a robot's coarse grid along its longest side (0: no coarse correction)")
        .within(0, kMaxCoarseCells);
    v.field("coarse_refresh", coarse_refresh,
            "send the coarse blocks again when they changed by this fraction")
        .within(0.0, 1.0, core::Interval::open_high);
    v.field("coarse_trust", coarse_trust,
            "send fresh coarse blocks when the step fell short of this fraction of its prediction")
        .within(0.0, 1.0, core::Interval::open_high);
    v.field(
         "separator_tolerance", separator_tolerance,
         "send a separator whose factors' residuals moved by this fraction of the block's (0: all)")
        .nonNegative();
  }
};

/// Throws core::Error naming the first field that breaks its rule (visit()).
void validate(const RefineConfig& config);

/// What one robot's step did and what it sends.
struct RefineStep {
  /// Per neighbour, the new estimates of the own poses that neighbour's
  /// factors touch and that moved by more than separator_tolerance from the
  /// value the neighbour holds (an entry for every neighbour, empty when none did).
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
  /// T_prev exp((1 + momentum) log(T_prev^-1 T_last)) per pose; then moved by
  /// the coarse step, when given (the group's step after the last kept round).
  void beginRound(double momentum = 0.0, const CoarseStep* coarse = nullptr);

  /// This robot's coarse grid, over its poses as the agent was made: what its
  /// neighbours need (setCoarseGrid) to share coarse terms of factors to it.
  /// None when coarse corrections are off or an own pose holds the gauge
  /// (the robot's poses then never move in a coarse step).
  [[nodiscard]] const std::optional<CoarseGrid>& coarseGrid() const;
  /// Takes in a neighbour's coarse grid.
  void setCoarseGrid(core::RobotId neighbour, const CoarseGrid& grid);
  /// This robot's share of the coarse problem at its current estimates and
  /// the neighbours' latest values: the factors it owns, linearised in the
  /// coarse unknowns of their ends (robots whose grid it has; own poses that
  /// hold the gauge and held neighbour poses never move). With `hessian`, the
  /// Gauss-Newton blocks too.
  [[nodiscard]] CoarseShare coarseShare(bool hessian) const;
  /// The share to send after a kept round: the gradient, and the blocks when
  /// they changed by more than coarse_refresh (relative, Frobenius) since the
  /// ones this agent last sent, it sent none, or `fresh` (the group's
  /// coarseScale asked for them). The group's solvers keep each robot's last blocks.
  CoarseShare shareCoarse(bool fresh = false);
  /// This robot's share of the graph's cost (ownedCost) with its poses and
  /// its copies of the neighbours' separators moved by `step` times each of
  /// kCoarseScales: what the group needs to pick the step's length (coarseScale).
  [[nodiscard]] std::array<double, kCoarseScales.size()> coarseTrialCosts(
      const CoarseStep& step) const;
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
  /// (RefineAgent::endRound). `coarse`: the round started with a coarse step,
  /// which, like momentum, is dropped for a round run again after one that
  /// rose; only a round with neither that rises ends the refinement.
  bool endRound(double cost, bool coarse = false);
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
  std::size_t coarse_shares = 0;     ///< coarse shares sent (one a robot and kept round)
  std::size_t coarse_blocks = 0;     ///< Gauss-Newton blocks in them, all robots and rounds
  std::size_t coarse_refreshes = 0;  ///< rounds after which every robot sent fresh blocks
  double seconds = 0.0;              ///< wall time
  bool converged = false;  ///< the rounds gained less than the tolerance before max_rounds
};

/// Everything the robots of refineDistributed hand each other, as they hand
/// it: for a caller that measures it on the wire. Unset members are not called.
struct RefineTraffic {
  using Poses = std::map<core::PoseKey, Eigen::Isometry3d>;
  /// A robot's separator poses for one neighbour after its step in `round`
  /// (round 0: where the refinement starts, before the first step).
  std::function<void(core::RobotId from, core::RobotId to, int round, const Poses& poses)>
      separators;
  /// A robot's share of the graph's cost at the end of `round`, to every member.
  std::function<void(core::RobotId from, int round, double share)> cost;
  /// A robot's coarse grid, once to each neighbour.
  std::function<void(core::RobotId from, core::RobotId to, const CoarseGrid& grid)> grid;
  /// A robot's coarse share after a kept round, to every member.
  std::function<void(int round, const CoarseShare& share)> coarse;
  /// A robot's costs of the coarse step at kCoarseScales, to every member.
  std::function<void(core::RobotId from, int round,
                     const std::array<double, kCoarseScales.size()>& costs)>
      coarse_costs;
};

/// Refines every estimate of `graph` in place by Gauss-Seidel block-coordinate
/// descent over its robots (key.robot), robots in id order, one agent each,
/// from its current estimates (DGS's result, or any other), each kept round
/// followed by the coarse correction.
/// The gauge: the graph's fixed nodes stay fixed. With none, no node is held
/// while the robots optimise (a held node makes the robot holding it bend its
/// whole part of the map around it, which block steps then undo only
/// slowly), and at the end each group of connected robots is moved rigidly so
/// that its lowest node is where it started, as solveCentralized holds it.
/// Factors naming a node the graph does not hold are skipped. Throws
/// core::Error when the configuration is out of range.
RefineSummary refineDistributed(PoseGraph& graph, const RefineConfig& config = {},
                                const RefineTraffic& traffic = {});

}  // namespace dcl::backend
