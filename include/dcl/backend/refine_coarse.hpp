#pragma once

/// The coarse level of the distributed refinement (distributed_refine.hpp).
///
/// Block-coordinate descent over robots solves each robot's block exactly,
/// but a correction that spans several robots (a heading error of a whole
/// corridor, a long chain bent at the gauge) crosses one robot boundary a
/// round, and the rounds needed grow with the map. As in two-level domain
/// decomposition, each round therefore ends with a coarse correction: a
/// smooth deformation of every robot's part of the map, solved for all
/// robots at once by Gauss-Newton on the whole graph's cost.
///
/// A robot's deformation lives on its own coarse grid: trilinear hat
/// functions on a regular grid over the box its poses filled when the
/// refinement started. Each grid node carries a small rigid motion [v; omega]
/// about the node; a pose at t moves by the weighted sum of its nodes'
/// motions, t += sum w (v + omega x (t - c)), R = exp(sum w omega) R. Within one
/// node's support a robot's poses move rigidly, so the coarse problem stays
/// small (at most (cells + 1)^3 nodes a robot) while it still bends a long
/// trajectory or turns one corridor against another.
///
/// Each robot linearises the factors it owns (ownership as in
/// RefineAgent::ownedCost) in the coarse unknowns of their two ends and
/// shares the result (CoarseShare): its gradient every round, its Gauss-Newton
/// blocks only when the group refreshes them. Every robot adds up the same
/// shares in the same order (CoarseSolver) and so takes the same coarse step;
/// it moves its own poses and its copies of its neighbours' separators by it,
/// so the step needs no separator message. A robot needs its neighbours'
/// grids (sent once) to weigh their separators.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstddef>
#include <map>
#include <memory>
#include <utility>
#include <vector>

#include <dcl/core/ids.hpp>
#include <dcl/core/se3.hpp>

namespace dcl::backend {

/// A node of a robot's coarse grid: the robot and the node's index in it.
using CoarseNode = std::pair<core::RobotId, int>;

/// A robot's coarse grid (what it tells its neighbours once).
struct CoarseGrid {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();  ///< position of node (0, 0, 0)
  double cell = 1.0;                                 ///< m between neighbouring nodes
  Eigen::Vector3i nodes = Eigen::Vector3i::Ones();   ///< per axis; 1: flat along it

  [[nodiscard]] int size() const { return nodes.prod(); }
};

/// A grid over the box of `positions` with `cells` cells along its longest
/// side; a side shorter than a hundredth of a cell is flat (one node), any
/// other gets as many cells as the cell size fills, at least one. Fewer cells
/// when the positions would touch more than a quarter as many nodes as there
/// are positions; a single node (one rigid motion about the box's centre)
/// when even one cell would.
CoarseGrid makeCoarseGrid(const std::vector<Eigen::Vector3d>& positions, int cells);

/// One hat function's weight at a point, and where its node is.
struct CoarseWeight {
  int node = 0;
  double weight = 0.0;
  Eigen::Vector3d centre = Eigen::Vector3d::Zero();
};

/// The nonzero hat functions of `grid` at `p` (at most eight; they sum to 1).
/// Outside the box the nearest point of the box is used.
std::vector<CoarseWeight> coarseWeights(const CoarseGrid& grid, const Eigen::Vector3d& p);

/// The coarse unknowns' values: a motion [v; omega] about each node.
struct CoarseStep {
  std::map<CoarseNode, core::Vector6d> motion;
  /// The chi-square's first-order change along the step, 2 g^T x: the
  /// Gauss-Newton model predicts a fall of half its magnitude.
  double slope = 0.0;
};

/// `step` with every motion (and its slope) times `scale`.
CoarseStep scaled(const CoarseStep& step, double scale);

/// The scales of the coarse step every robot prices before the group takes
/// one (coarseScale). The model's blocks may be rounds old, and a step that
/// was right for them can overshoot or fall short; trying a few lengths costs
/// each robot four numbers, not another round.
inline constexpr std::array<double, 4> kCoarseScales{0.5, 1.0, 1.5, 2.0};

/// The group's choice among the priced scales of a coarse step.
struct CoarseChoice {
  double scale = 0.0;    ///< of the step to take (0: none lowers the cost)
  bool refresh = false;  ///< the model predicted badly: every robot sends fresh blocks next
};

/// Picks the scale of kCoarseScales whose cost (`costs`, the group's sum of
/// RefineAgent::coarseTrialCosts) is lowest and below `cost`, the cost
/// without the step. The model is refreshed when the fall it gives is less
/// than `trust` times the fall the Gauss-Newton model predicts at scale 1:
/// then the blocks, not the step's length, are wrong (a stale model's step
/// on manhattan in 9 robots rises by 1 % to 50 % at every length).
CoarseChoice coarseScale(const CoarseStep& step, double cost,
                         const std::array<double, kCoarseScales.size()>& costs, double trust);

/// `T_world_node` of robot `robot` (whose grid is `grid`) moved by `step`.
Eigen::Isometry3d applyCoarse(const CoarseStep& step, core::RobotId robot, const CoarseGrid& grid,
                              const Eigen::Isometry3d& T_world_node);

/// Blocks (a, b) of a Gauss-Newton matrix J^T J, a <= b.
using CoarseBlocks = std::map<std::pair<CoarseNode, CoarseNode>, core::Matrix6d>;

/// |new - old|_F / |old|_F over the blocks of both (a block one lacks counts as zero).
double relativeChange(const CoarseBlocks& now, const CoarseBlocks& before);

/// A robot's share of the round's coarse problem: its owned factors'
/// Gauss-Newton terms in the coarse unknowns (J^T r, and J^T J when sent).
struct CoarseShare {
  core::RobotId robot;
  std::map<CoarseNode, core::Vector6d> gradient;
  /// Empty: the robot's blocks are those it last sent.
  CoarseBlocks hessian;
};

/// One coarse column of a factor: d residual / d motion of `node`.
struct CoarseColumn {
  CoarseNode node;
  core::Matrix6d J = core::Matrix6d::Zero();
};

/// The columns of a pose's end of a factor: `J` (the whitened residual's
/// Jacobian in the right perturbation of that pose) through each hat function
/// of the pose's robot's grid.
void appendCoarseColumns(std::vector<CoarseColumn>& columns, const core::Matrix6d& J,
                         core::RobotId robot, const CoarseGrid& grid,
                         const Eigen::Isometry3d& T_world_node);

/// Adds one factor (whitened residual `r`, its coarse columns) to `share`;
/// its Gauss-Newton blocks too when `hessian`.
void addToShare(CoarseShare& share, const core::Vector6d& r,
                const std::vector<CoarseColumn>& columns, bool hessian);

/// Every robot's copy of the group's coarse problem: each robot's last sent
/// blocks, their sum factorised once a round that brought new ones, and the
/// step from each round's gradients. Shares must come in the same order on
/// every robot.
class CoarseSolver {
 public:
  /// `damping`: Levenberg-Marquardt damping relative to the diagonal, which
  /// also fixes the group's gauge (a rigid motion of everything costs nothing).
  explicit CoarseSolver(double damping = 1e-4);
  ~CoarseSolver();
  CoarseSolver(CoarseSolver&&) noexcept;
  CoarseSolver& operator=(CoarseSolver&&) noexcept;

  /// The step -(H + damping D)^-1 g. A share's blocks replace its robot's
  /// last ones; gradient entries of nodes the matrix lacks are left out.
  /// Empty before any blocks or when the matrix cannot be factorised.
  CoarseStep solve(const std::vector<CoarseShare>& shares);

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace dcl::backend
