#include <cmath>
#include <limits>
#include <map>
#include <utility>

#include <dcl/backend/centralized_solver.hpp>
#include <dcl/core/error.hpp>
#include <dcl/eval/alignment.hpp>
#include <dcl/eval/association.hpp>
#include <dcl/eval/ate.hpp>
#include <dcl/eval/bound.hpp>

namespace dcl::eval {
namespace {

/// Robot r's keyframes in `graph`, paired with its ground truth.
Association pairsOf(const RobotGraph& r, const backend::PoseGraph& graph) {
  std::vector<Eigen::Isometry3d> poses;
  for (std::size_t k = 0; k < r.stamps.size(); ++k)
    poses.push_back(graph.estimate({r.id, core::KeyframeId(k)}));
  const core::Trajectory estimate(r.stamps, std::move(poses));
  return associateByTimestamp(estimate, r.ground_truth, 0.01);
}

/// The joint graph's costs at the run and at its optimum, with and without
/// the robots that left.
JointCosts jointCosts(const std::vector<RobotGraph>& robots, const backend::PoseGraph& optimum) {
  JointCosts costs;
  costs.run = backend::graphCost(jointGraph(robots, JointFactors::joint));
  costs.optimum = backend::graphCost(optimum);
  std::vector<RobotGraph> stayed;
  for (const RobotGraph& r : robots) {
    if (r.left)
      costs.left.push_back(r.name);
    else
      stayed.push_back(r);
  }
  if (!costs.left.empty() && !stayed.empty()) {
    costs.stayed_run = backend::graphCost(jointGraph(stayed, JointFactors::joint));
    costs.stayed_optimum = backend::graphCost(solveJointGraph(stayed, JointFactors::joint));
  }
  return costs;
}

}  // namespace

backend::PoseGraph solveJointGraph(const std::vector<RobotGraph>& robots, JointFactors factors) {
  backend::SolverConfig solver;
  solver.max_iterations = 200;
  backend::PoseGraph g = jointGraph(robots, factors);
  backend::PoseGraph chordal = g;
  const double from_run = backend::solveCentralized(g, solver).final_cost;
  backend::SolverConfig from_scratch = solver;
  from_scratch.initialisation = "chordal";
  return backend::solveCentralized(chordal, from_scratch).final_cost < from_run ? chordal : g;
}

double robotAte(const RobotGraph& r, const backend::PoseGraph& graph) {
  try {
    return computeAte(pairsOf(r, graph), Alignment::se3).translation_m.rmse;
  } catch (const core::Error&) {
    return std::numeric_limits<double>::quiet_NaN();
  }
}

std::vector<double> jointAtes(const std::vector<RobotGraph>& robots,
                              const backend::PoseGraph& graph) {
  const std::vector<std::size_t> group = loopGroups(robots);
  std::vector<Association> pairs;
  std::map<std::size_t, Association> all;
  for (std::size_t i = 0; i < robots.size(); ++i) {
    pairs.push_back(pairsOf(robots[i], graph));
    const Association& p = pairs.back();
    Association& mine = all[group[i]];
    for (std::size_t k = 0; k < p.size(); ++k) {
      mine.estimate.push_back(p.estimate.stamp(k), p.estimate.pose(k));
      mine.ground_truth.push_back(p.ground_truth.stamp(k), p.ground_truth.pose(k));
    }
  }
  std::vector<double> out(robots.size(), std::numeric_limits<double>::quiet_NaN());
  for (const auto& [g, together] : all) {
    try {
      const Sim3 S_gt_common = computeAlignment(together, Alignment::se3);
      for (std::size_t i = 0; i < robots.size(); ++i) {
        if (group[i] != g || pairs[i].size() == 0) continue;
        out[i] = computeAte(pairs[i], S_gt_common, Alignment::se3).translation_m.rmse;
      }
    } catch (const core::Error&) {
    }
  }
  return out;
}

std::vector<RobotBound> computeBound(const std::vector<RobotGraph>& robots, JointCosts* costs) {
  const backend::PoseGraph odometry = solveJointGraph(robots, JointFactors::odometry);
  const backend::PoseGraph own_loops = solveJointGraph(robots, JointFactors::own_loops);
  const backend::PoseGraph optimum = solveJointGraph(robots, JointFactors::joint);
  const backend::PoseGraph exact = solveJointGraph(robots, JointFactors::exact);
  if (costs != nullptr) *costs = jointCosts(robots, optimum);
  backend::PoseGraph run_graph;  ///< every robot's own keyframes where the run left them
  for (const RobotGraph& r : robots)
    for (const auto& [key, T] : r.graph.nodes()) run_graph.addNode(key, T);
  const std::vector<double> run_joint = jointAtes(robots, run_graph);
  const std::vector<double> optimum_joint = jointAtes(robots, optimum);
  const std::vector<double> exact_joint = jointAtes(robots, exact);
  std::vector<RobotBound> out;
  for (std::size_t i = 0; i < robots.size(); ++i) {
    const RobotGraph& r = robots[i];
    out.push_back({r.name, robotAte(r, odometry), robotAte(r, own_loops), robotAte(r, r.graph),
                   robotAte(r, optimum), robotAte(r, exact), run_joint[i], optimum_joint[i],
                   exact_joint[i], r.left});
  }
  return out;
}

double meanLowered(const std::vector<RobotBound>& robots, double RobotBound::*value,
                   double RobotBound::*base) {
  double sum = 0.0;
  std::size_t counted = 0;
  for (const RobotBound& r : robots) {
    if (!(r.*base > 0.0) || std::isnan(r.*value)) continue;
    sum += 1.0 - r.*value / r.*base;
    ++counted;
  }
  return counted == 0 ? 0.0 : sum / static_cast<double>(counted);
}

std::size_t notBelow(const std::vector<RobotBound>& robots, double RobotBound::*value,
                     double RobotBound::*base) {
  std::size_t n = 0;
  for (const RobotBound& r : robots) n += r.*value >= r.*base ? 1 : 0;  // false for NaN
  return n;
}

}  // namespace dcl::eval
