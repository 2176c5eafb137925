#pragma once

/// The second line of defence after PCM: inter-robot loops that the group's
/// joint solution cannot explain.
///
/// PCM judges each robot pair alone. A cluster of wrong loops that agree with
/// each other (one repeated block seen from a few keyframes, or two aliases
/// the same shift apart along a straight corridor) passes it whenever the
/// pair holds nothing better: the pair's own trajectories cannot refute a
/// rigid shift. The robots' other loops can: solved together, the group's
/// graph closes cycles through a third robot, and a wrong cluster leaves an
/// error of metres in them.
///
/// Least squares spreads that error over every factor of the cycles, and a
/// long odometry chain bending a little at each step hides it; the check
/// therefore solves with each robot's own factors held stiffer than their
/// covariances say (odometry_stiffness), so the error stays on the loops.
/// A loop whose residual then lies beyond a threshold far in the tail of a
/// consistent loop's distribution is unexplained. Which loops to withdraw is a
/// question of support, as in PCM: any robot pair of an inconsistent cycle
/// could open it, and the check opens it at the pair with the fewest loops
/// whose withdrawal leaves every other loop explained, then solves and checks
/// again.

#include <Eigen/Geometry>
#include <cstddef>
#include <functional>
#include <optional>
#include <utility>
#include <vector>

#include <dcl/backend/centralized_solver.hpp>
#include <dcl/backend/pcm.hpp>
#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/ids.hpp>

namespace dcl::backend {

/// How the joint solution's check of inter-robot loops decides.
struct LoopCheckConfig {
  bool enabled = true;  ///< withdraw loops the group's solution cannot explain
  /// Squared Mahalanobis distance of a loop's residual at the joint solution
  /// beyond which the solution does not explain it. A loop consistent with
  /// its covariance stays under chi-square(6)'s 99.99 % point, 27.9; the
  /// simulated swarms' true loops stay far under (their covariances are
  /// wider than their errors: NEES 0.02-0.25 a degree of freedom), and a
  /// wrong loop metres off lies in the thousands.
  double threshold = 100.0;
  /// How many times stiffer than their covariances say each robot's own
  /// factors (odometry, intra-robot loops) are held while the check solves.
  /// Least squares spreads a wrong loop's error over every factor of the
  /// cycles it closes; a long odometry chain then bends a little at every
  /// step and the loop looks explained. Held stiff, the chains keep their
  /// shape over the few keyframes a meeting spans and the error stays on the
  /// loops, most on the pair with the least support.
  double odometry_stiffness = 100.0;

  /// Lists the fields and their rules (core/config.hpp).
  template <class V>
  void visit(V& v) {
    v.field("enabled", enabled,
            "withdraw inter-robot loops the group's joint solution cannot "
            "explain (the second line of defence after PCM)");
    v.field("threshold", threshold,
            "squared Mahalanobis distance of a loop's residual beyond which it is unexplained")
        .positive();
    v.field("odometry_stiffness", odometry_stiffness,
            "times the robots' own factors are held stiffer than their covariances while the "
            "check solves (the offline check)")
        .positive();
  }
};

/// One inter-robot loop at a solution.
struct LoopResidual {
  LoopId id;          ///< the loop (lower robot's key first)
  double chi2 = 0.0;  ///< r^T Omega r of its residual
};

/// The loops of one robot pair the solution does not explain.
struct Unexplained {
  std::pair<core::RobotId, core::RobotId> robots;  ///< the pair, lower first
  std::vector<LoopId> loops;                       ///< its loops beyond the threshold
  double worst_chi2 = 0.0;                         ///< the largest of their chi-squares
};

/// Where a solution puts a node; none when it does not hold it.
using PoseLookup = std::function<std::optional<Eigen::Isometry3d>(const core::PoseKey&)>;

/// The residuals of the inter-robot `loops` whose two ends `poses` holds.
std::vector<LoopResidual> loopResiduals(const std::vector<Factor>& loops, const PoseLookup& poses);

/// The robot pair whose worst loop has the largest chi-square, with its
/// loops beyond the threshold; none when every loop is explained. (What a
/// robot can judge alone from its round's solution, RobotNode.)
std::optional<Unexplained> worstUnexplained(const std::vector<LoopResidual>& residuals,
                                            const LoopCheckConfig& config = {});

/// The check on a whole graph, centrally: solve with stiff odometry; while a
/// loop is unexplained, withdraw the loops of the least-supported pair whose
/// withdrawal explains the rest (the worst loop's pair when none does) and
/// solve again. `graph` keeps the loops left, solved with the factors'
/// own weights; returns those withdrawn, in the order they were.
std::vector<LoopId> withdrawUnexplained(PoseGraph& graph, const LoopCheckConfig& config = {},
                                        const SolverConfig& solver = {});

/// The check after PCM on a multi-robot graph: its own factors (odometry,
/// intra-robot loops) and the loops `result` kept, solved from the chordal
/// initialisation; the loops withdrawn move from their pair's accepted set
/// to its withdrawn one. Returns how many were withdrawn.
std::size_t checkKeptLoops(const PoseGraph& graph, PcmResult& result,
                           const LoopCheckConfig& config = {});

}  // namespace dcl::backend
