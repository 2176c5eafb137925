#include <chrono>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <ceres/ceres.h>

#include <dcl/backend/centralized_solver.hpp>
#include <dcl/backend/dgs.hpp>
#include <dcl/core/config.hpp>
#include <dcl/core/error.hpp>

#include "se3_cost.hpp"

namespace dcl::backend {
namespace {

ceres::LossFunction* makeLoopLoss(const SolverConfig& config) {
  if (config.loop_loss == "none") return nullptr;
  if (config.loop_loss == "huber") return new ceres::HuberLoss(config.loss_scale);
  if (config.loop_loss == "cauchy") return new ceres::CauchyLoss(config.loss_scale);
  throw core::Error("solver: unknown loop_loss '" + config.loop_loss +
                    "' (expected none, huber or cauchy)");
}

/// The Ceres problem over a graph: blocks for every node a factor touches.
class GraphProblem {
 public:
  GraphProblem(const PoseGraph& graph, const SolverConfig& config,
               std::unique_ptr<ceres::LossFunction> loop_loss)
      : loop_loss_(std::move(loop_loss)) {
    for (const auto& [key, pose] : graph.nodes()) problem_.setPose(key, pose);
    for (const Factor& f : graph.factors()) {
      if (!problem_.addFactor(f, isLoop(f.kind) ? loop_loss_.get() : nullptr)) ++skipped_;
    }
    fixGauge(graph, config.fix_lowest);
  }

  ceres::Problem& problem() { return problem_.problem(); }
  [[nodiscard]] std::size_t factors() const { return problem_.factors(); }
  [[nodiscard]] std::size_t skipped() const { return skipped_; }

  /// Writes the optimised blocks back; fixed and unconstrained nodes keep their exact estimates.
  void writeBack(PoseGraph& graph) const {
    for (const auto& [key, block] : problem_.blocks()) {
      if (problem_.isVariable(key)) graph.setEstimate(key, detail::fromBlock(block));
    }
  }

 private:
  void fixGauge(const PoseGraph& graph, bool fix_lowest) {
    std::vector<core::PoseKey> fixed(graph.fixedNodes().begin(), graph.fixedNodes().end());
    if (fixed.empty() && fix_lowest && graph.size() > 0)
      fixed.push_back(graph.nodes().begin()->first);
    for (const core::PoseKey& key : fixed) problem_.setConstant(key);
  }

  std::unique_ptr<ceres::LossFunction> loop_loss_;  // outlives the problem that uses it
  detail::Se3Problem problem_;
  std::size_t skipped_ = 0;
};

void initialise(PoseGraph& graph, const std::string& initialisation) {
  if (initialisation == "chordal") {
    chordalInitialise(graph);
  } else if (initialisation != "as_is") {
    throw core::Error("solver: unknown initialisation '" + initialisation +
                      "' (expected as_is or chordal)");
  }
}

}  // namespace

void validate(const SolverConfig& config) {
  core::checkConfig(config, "solver config");
}

SolverSummary solveCentralized(PoseGraph& graph, const SolverConfig& config) {
  validate(config);
  const auto start = std::chrono::steady_clock::now();
  SolverSummary summary;
  summary.initial_cost = graphCost(graph);
  std::unique_ptr<ceres::LossFunction> loop_loss(makeLoopLoss(config));  // throws before any change
  initialise(graph, config.initialisation);
  summary.initialised_cost = graphCost(graph);
  GraphProblem problem(graph, config, std::move(loop_loss));
  summary.factors = problem.factors();
  summary.skipped_factors = problem.skipped();
  if (problem.factors() > 0) {
    ceres::Solver::Summary ceres_summary;
    ceres::Solve(detail::levenbergMarquardt(config.max_iterations, config.threads,
                                            config.function_tolerance),
                 &problem.problem(), &ceres_summary);
    problem.writeBack(graph);
    summary.iterations = ceres_summary.num_successful_steps + ceres_summary.num_unsuccessful_steps;
    summary.converged = ceres_summary.termination_type == ceres::CONVERGENCE;
    summary.message = ceres_summary.message;
  } else {
    summary.converged = true;
    summary.message = "no factor to optimise";
  }
  summary.final_cost = graphCost(graph);
  summary.time = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  return summary;
}

}  // namespace dcl::backend
