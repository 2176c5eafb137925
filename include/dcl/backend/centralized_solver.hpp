#pragma once

/// The centralized pose-graph solver (Ceres): the reference every distributed
/// result is measured against (DESIGN.md §5), and the smoother of a robot's
/// local graph. Each pose is a unit quaternion (Ceres' EigenQuaternionManifold)
/// and a translation; each factor's residual is the SE(3) log of the
/// measurement error (pose_graph.hpp), whitened by the square root of its
/// information. Ceres stays inside the source file.

#include <cstddef>
#include <string>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/config.hpp>

namespace dcl::backend {

/// How the centralized solver runs.
struct SolverConfig {
  static constexpr int kMaxThreads = 256;  ///< threads at most (Ceres starts them all)

  int max_iterations = 100;  ///< Levenberg-Marquardt iterations at most
  int threads = 1;           ///< threads for Jacobian evaluation and the linear solver
  /// Robust loss on loop factors only (odometry is trusted): "none", "huber" or "cauchy".
  std::string loop_loss = "none";
  /// Scale of the loss in whitened units (sqrt of chi-square): 3.55 = sqrt of
  /// chi-square(6) at 95 %, so a loop consistent with its covariance is not down-weighted.
  double loss_scale = 3.55;
  /// Fix the lowest node when the graph fixes none (else the gauge is free and
  /// Levenberg-Marquardt damping alone pins it).
  bool fix_lowest = true;
  double function_tolerance = 1e-8;  ///< stop when the relative cost change falls below
  /// Where Levenberg-Marquardt starts: "as_is" (the graph's estimates) or
  /// "chordal" (chordalInitialise of dgs.hpp, rotations from the chordal
  /// relaxation, then translations). From odometry-composed estimates LM can end
  /// in a local minimum (torus3D); from the chordal start it reaches the optimum.
  std::string initialisation = "as_is";

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("max_iterations", max_iterations, "Levenberg-Marquardt iterations at most")
        .nonNegative();
    v.field("threads", threads, "threads for Jacobians and the linear solver")
        .within(1, kMaxThreads);
    v.field("loop_loss", loop_loss, "robust loss on loop factors: none, huber or cauchy")
        .oneOf({"none", "huber", "cauchy"});
    v.field("loss_scale", loss_scale, "scale of the loss, whitened units (sqrt chi-square)")
        .positive();
    v.field("fix_lowest", fix_lowest, "fix the lowest node when the graph fixes none");
    v.field("function_tolerance", function_tolerance, "stop below this relative cost change")
        .nonNegative();
    v.field("initialisation", initialisation, "where LM starts: as_is or chordal")
        .oneOf({"as_is", "chordal"});
  }
};

/// Throws core::Error naming the first field that breaks its rule (visit()).
void validate(const SolverConfig& config);

/// What a solve did. Costs are g2o's chi-square, sum of r^T Omega r over the
/// factors that connect two nodes, without the robust loss, so that they
/// compare with published figures.
struct SolverSummary {
  double initial_cost = 0.0;      ///< chi-square before
  double initialised_cost = 0.0;  ///< chi-square where Levenberg-Marquardt starts
  double final_cost = 0.0;        ///< chi-square after
  int iterations = 0;             ///< iterations run (successful and unsuccessful)
  bool converged = false;         ///< a tolerance was met (not the iteration cap or a failure)
  double time = 0.0;              ///< s, wall time of the solve
  std::size_t factors = 0;        ///< factors in the problem
  /// Factors naming a node the graph does not hold, or one node twice (a constant cost).
  std::size_t skipped_factors = 0;
  std::string message;  ///< Ceres' termination message
};

/// Optimises every node estimate of `graph` in place. Fixed nodes keep their
/// estimates; with `config.fix_lowest` and no fixed node, the lowest key is
/// fixed (the graph itself is not marked). Throws core::Error for a config
/// that breaks its rules (validate), or when the chordal initialisation fails
/// (a graph in pieces).
SolverSummary solveCentralized(PoseGraph& graph, const SolverConfig& config = {});

}  // namespace dcl::backend
