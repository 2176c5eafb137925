#pragma once

/// Levenberg-Marquardt over one block of an SE(3) pose graph whose structure
/// rarely changes, for the distributed refinement (distributed_refine.hpp).
/// A robot solves its block once a round for tens to hundreds of rounds, each
/// solve a few iterations from a nearby start. Ceres analyses the problem
/// afresh in every Solve() (reduced program, fill-reducing ordering, symbolic
/// factorisation), and on sphere2500 in four robots that analysis and its
/// supernodal machinery took most of the refinement's time. Here the normal
/// equations' sparsity pattern, where each factor's 6x6 blocks land in it,
/// and the ordering are worked out once, when a factor or a constant pose is
/// added; an iteration then only fills in values and refactorises
/// numerically (CHOLMOD's supernodal Cholesky,
/// through Eigen).
///
/// The cost is the centralized solver's, term for term
/// (RelativePoseMeasurement in se3_cost.hpp): poses are a unit quaternion and
/// a translation, stepped by right perturbations T exp([rho; phi]).
/// Internal to the backend.

#include <Eigen/Geometry>
#include <Eigen/SparseCore>
#include <cstddef>
#include <map>
#include <memory>
#include <vector>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/ids.hpp>

#include "se3_cost.hpp"

namespace dcl::backend::detail {

/// What one solve did. Costs are chi-square (twice Ceres' cost) over the
/// factors with a free end.
struct BlockSolveSummary {
  double initial_cost = 0.0;
  double final_cost = 0.0;
  int iterations = 0;  ///< steps tried, taken or not
};

/// Termination, as Ceres' options of the same names.
struct BlockSolveOptions {
  int max_iterations = 10;
  double function_tolerance = 1e-6;   ///< relative cost decrease of a taken step
  double gradient_tolerance = 1e-10;  ///< max-norm of the gradient
  double parameter_tolerance = 1e-8;  ///< step norm relative to the free poses' norm
  /// Steps a factorisation may serve after the one it was made for, across
  /// solves: the block's curvature changes little from one round to the next.
  /// A step from an old factorisation that does not lower the cost is tried
  /// again at once from a fresh one.
  int factorisation_reuse = 0;
};

/// Named poses and the factors between them; constant poses are the gauge or
/// a neighbour's separators, whose values may be replaced between solves.
class PoseBlockSolver {
 public:
  PoseBlockSolver();
  ~PoseBlockSolver();
  PoseBlockSolver(const PoseBlockSolver&) = delete;
  PoseBlockSolver& operator=(const PoseBlockSolver&) = delete;

  /// Adds pose `key` at `T_world_node`, or replaces its value.
  void setPose(const core::PoseKey& key, const Eigen::Isometry3d& T_world_node);
  [[nodiscard]] bool hasPose(const core::PoseKey& key) const { return index_.contains(key); }
  /// The current value of pose `key` (which must exist).
  [[nodiscard]] Eigen::Isometry3d pose(const core::PoseKey& key) const;

  /// Adds the factor; false, and nothing added, when an end is not a pose or
  /// both ends are the same pose (its cost is a constant).
  bool addFactor(const Factor& f);
  /// Holds pose `key` constant when a factor uses it; false when none does.
  bool setConstant(const core::PoseKey& key);
  /// True when pose `key` is in a factor and free to move.
  [[nodiscard]] bool isVariable(const core::PoseKey& key) const;
  [[nodiscard]] std::size_t factors() const { return edges_.size(); }

  /// Levenberg-Marquardt from the current values (Marquardt's diagonal
  /// scaling, Nielsen's damping update, the damping carried from one solve to
  /// the next); a step is taken only when it lowers the cost, so the final
  /// cost is never above the initial one.
  BlockSolveSummary solve(const BlockSolveOptions& options);

 private:
  struct Pose {
    Eigen::Quaterniond q = Eigen::Quaterniond::Identity();
    Eigen::Vector3d t = Eigen::Vector3d::Zero();
    bool used = false;      // a factor touches it
    bool constant = false;  // held
    int unknown = -1;       // first of its six unknowns; -1: not free
  };
  struct Edge {
    int from = 0;
    int to = 0;
    RelativePoseMeasurement measurement;
    // Offsets into the normal matrix's values of the blocks (from,from),
    // (to,to), (from,to) and (to,from); -1 where an end is not free.
    std::ptrdiff_t block[4] = {-1, -1, -1, -1};
  };

  void analyse();
  /// Factorises the damped normal equations; false when they are not positive definite.
  bool factorise();
  /// After a step that did not lower the cost: more damping, a fresh factorisation.
  void reject();
  /// Chi-square over the edges with a free end; the normal equations too when asked.
  double evaluate(const std::vector<Pose>& poses, bool normal_equations);
  [[nodiscard]] std::vector<Pose> stepped(const Eigen::VectorXd& delta) const;

  std::map<core::PoseKey, int> index_;
  std::vector<Pose> poses_;
  std::vector<Edge> edges_;
  bool analysed_ = false;
  int unknowns_ = 0;
  std::vector<int> active_;               // edges with a free end
  Eigen::SparseMatrix<double> hessian_;   // J^T J, both triangles, 6x6 blocks
  std::vector<std::ptrdiff_t> diagonal_;  // value offset of every diagonal entry
  Eigen::VectorXd gradient_;              // J^T r
  Eigen::SparseMatrix<double> damped_;    // hessian_ plus the damping, same pattern
  struct Cholesky;                        // CHOLMOD's supernodal LL^T, kept out of this header
  std::unique_ptr<Cholesky> cholesky_;
  bool factorised_ = false;  // cholesky_ holds a factorisation of the current pattern
  int reused_ = 0;           // steps it served after its first
  double lambda_ = 1e-4;     // Ceres' initial trust region radius is 1e4 = 1 / lambda
  double nu_ = 2.0;
};

}  // namespace dcl::backend::detail
