// dcl-slam bench bound: see bound.hpp.

#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <memory>
#include <optional>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/backend/centralized_solver.hpp>
#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/error.hpp>
#include <dcl/eval/association.hpp>
#include <dcl/eval/ate.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/g2o.hpp>
#include <dcl/io/pose_file.hpp>

#include "bound.hpp"
#include "commands.hpp"

namespace dcl::apps {
namespace {

using Json = nlohmann::ordered_json;

struct BoundOptions {
  std::string run;
  std::string dataset;
  bool json = false;
};

/// One robot of the run: its keyframes' stamps and ground truth, and its graph.
struct RobotGraph {
  std::string name;
  core::RobotId id;
  std::vector<double> stamps;                 ///< per keyframe (trajectory.tum)
  std::vector<Eigen::Isometry3d> T_world_gt;  ///< ground truth at each keyframe
  core::Trajectory ground_truth;
  backend::PoseGraph graph;  ///< own keyframes at the run's estimates, every factor
};

RobotGraph readRobot(const std::string& run, const io::DatasetSpec& spec, std::size_t index) {
  RobotGraph r;
  r.name = spec.robots[index].name;
  r.id = core::RobotId(static_cast<std::uint8_t>(index));
  const std::string folder = run + "/" + r.name;
  const core::Trajectory keyframes = io::readTumPoses(folder + "/trajectory.tum");
  r.ground_truth = io::readGroundTruth(spec, index);
  const backend::PoseGraph all = backend::fromG2o(io::readG2o(folder + "/graph.g2o"));
  for (const auto& [key, T] : all.nodes())
    if (key.robot == r.id) r.graph.addNode(key, T);
  for (const backend::Factor& f : all.factors()) r.graph.addFactor(f);
  if (r.graph.size() != keyframes.size()) {
    throw core::Error(
        fmt::format("{}/graph.g2o: {} keyframes of robot '{}', but trajectory.tum has {}", folder,
                    r.graph.size(), r.name, keyframes.size()));
  }
  for (std::size_t k = 0; k < keyframes.size(); ++k) {
    if (!r.graph.hasNode({r.id, core::KeyframeId(k)})) {
      throw core::Error(
          fmt::format("{}/graph.g2o: no vertex for keyframe {} of robot '{}'", folder, k, r.name));
    }
    const auto gt = r.ground_truth.at(keyframes.stamp(k));
    if (!gt) {
      throw core::Error(fmt::format("{}: no ground truth at keyframe {} (t = {} s)", folder, k,
                                    keyframes.stamp(k)));
    }
    r.stamps.push_back(keyframes.stamp(k));
    r.T_world_gt.push_back(*gt);
  }
  return r;
}

/// The ATE RMSE (m, per-robot SE(3) alignment, as the run's metrics) of
/// robot `r`'s keyframes at the estimates of `graph`; NaN when they cannot be
/// aligned (a robot that has not moved yet).
double ateOf(const RobotGraph& r, const backend::PoseGraph& graph) {
  std::vector<Eigen::Isometry3d> poses;
  for (std::size_t k = 0; k < r.stamps.size(); ++k)
    poses.push_back(graph.estimate({r.id, core::KeyframeId(k)}));
  const core::Trajectory estimate(r.stamps, std::move(poses));
  const eval::Association pairs = eval::associateByTimestamp(estimate, r.ground_truth, 0.01);
  try {
    return eval::computeAte(pairs, eval::Alignment::se3).translation_m.rmse;
  } catch (const core::Error&) {
    return std::numeric_limits<double>::quiet_NaN();
  }
}

/// What of the run's factors a graph holds.
enum class Factors {
  odometry,   ///< each robot's odometry
  own_loops,  ///< and its intra-robot loops
  joint,      ///< and the inter-robot loops, once each
  exact,      ///< the same with the inter-robot loops' measurements from the ground truth
};

/// The graph of the robots' own nodes, at the run's estimates, with `factors`.
backend::PoseGraph jointGraph(const std::vector<RobotGraph>& robots, Factors factors) {
  const bool inter = factors == Factors::joint || factors == Factors::exact;
  const bool true_loops = factors == Factors::exact;
  std::map<core::RobotId, const RobotGraph*> by_id;
  for (const RobotGraph& r : robots) by_id[r.id] = &r;
  backend::PoseGraph joint;
  std::set<std::pair<core::PoseKey, core::PoseKey>> loops;
  std::set<core::RobotId> tied;  ///< robots with an inter-robot loop in the graph
  for (const RobotGraph& r : robots) {
    for (const auto& [key, T] : r.graph.nodes()) joint.addNode(key, T);
    for (backend::Factor f : r.graph.factors()) {
      if (f.from.robot == f.to.robot) {
        if (f.from.robot == r.id &&
            (f.kind == backend::FactorKind::odometry || factors != Factors::odometry))
          joint.addFactor(f);
        continue;
      }
      if (!inter || !by_id.contains(f.from.robot) || !by_id.contains(f.to.robot)) continue;
      const auto pair = std::minmax(f.from, f.to);
      if (!loops.insert({pair.first, pair.second}).second) continue;
      if (true_loops) {
        const RobotGraph& a = *by_id.at(f.from.robot);
        const RobotGraph& b = *by_id.at(f.to.robot);
        const std::size_t i = f.from.keyframe.value(), j = f.to.keyframe.value();
        if (i >= a.T_world_gt.size() || j >= b.T_world_gt.size()) continue;
        f.T_from_to = a.T_world_gt[i].inverse() * b.T_world_gt[j];
      }
      joint.addFactor(f);
      tied.insert({f.from.robot, f.to.robot});
    }
  }
  // Every robot's first keyframe holds its frame: a robot without loops would
  // otherwise float, and the others are moved by their loops regardless.
  for (const RobotGraph& r : robots)
    if (!tied.contains(r.id) || &r == &robots.front()) joint.fix({r.id, core::KeyframeId(0)});
  return joint;
}

void runBound(const BoundOptions& o) {
  const std::vector<RobotBound> robots = computeBound(o.run, o.dataset);
  const std::vector<std::pair<const char*, double RobotBound::*>> columns{
      {"odometry", &RobotBound::odometry},
      {"own_loops", &RobotBound::own_loops},
      {"run", &RobotBound::run},
      {"optimum", &RobotBound::optimum},
      {"exact", &RobotBound::exact}};
  if (o.json) {
    Json out{{"run", o.run}, {"dataset", o.dataset}, {"robots", Json::array()}};
    for (const RobotBound& r : robots) {
      Json j{{"name", r.name}};
      for (const auto& [key, field] : columns) j[std::string("ate_") + key] = r.*field;
      out["robots"].push_back(j);
    }
    out["lowered"] = Json::object();
    for (std::size_t c = 1; c < columns.size(); ++c) {
      double RobotBound::*const value = columns[c].second;
      out["lowered"][columns[c].first] = {
          {"mean_ate_lowered", meanLowered(robots, value, &RobotBound::odometry)},
          {"robots_not_below_odometry", notBelow(robots, value, &RobotBound::odometry)},
          {"robots_not_below_own_loops", notBelow(robots, value, &RobotBound::own_loops)}};
    }
    fmt::print("{}\n", out.dump(2));
    return;
  }
  fmt::print("ATE (m) per robot, each aligned on its own; lowered: against the odometry\n");
  fmt::print("{:<10}{:>12}{:>12}{:>12}{:>12}{:>12}\n", "robot", "odometry", "own loops", "the run",
             "optimum", "loops exact");
  for (const RobotBound& r : robots) {
    fmt::print("{:<10}", r.name);
    for (const auto& [key, field] : columns)
      fmt::print("{:>12}", std::isnan(r.*field) ? "-" : fmt::format("{:.4f}", r.*field));
    fmt::print("\n");
  }
  fmt::print("{:<10}{:>12}", "lowered", "");
  for (std::size_t c = 1; c < columns.size(); ++c) {
    fmt::print("{:>12}", fmt::format("{:.1f} %", 100.0 * meanLowered(robots, columns[c].second,
                                                                     &RobotBound::odometry)));
  }
  fmt::print("\n{:<10}{:>12}", "not below", "");
  for (std::size_t c = 1; c < columns.size(); ++c) {
    fmt::print("{:>12}",
               fmt::format("{} of {}", notBelow(robots, columns[c].second, &RobotBound::odometry),
                           robots.size()));
  }
  fmt::print("\n");
}

}  // namespace

std::vector<RobotBound> computeBound(const std::string& run, const std::string& dataset) {
  const io::DatasetSpec spec = io::readDataset(dataset);
  std::vector<RobotGraph> robots;
  for (std::size_t i = 0; i < spec.robots.size(); ++i) {
    if (!std::filesystem::exists(run + "/" + spec.robots[i].name + "/graph.g2o")) {
      throw core::Error("run '" + run + "' has no graph.g2o for robot '" + spec.robots[i].name +
                        "' of dataset '" + dataset + "' (is it the run of that dataset?)");
    }
    robots.push_back(readRobot(run, spec, i));
  }
  backend::SolverConfig solver;
  solver.max_iterations = 200;
  // From the run's estimates, and from the chordal initialisation: a run whose
  // robots ended in frames of different rounds is a poor start, and
  // Levenberg-Marquardt can settle in a local minimum from it. The lower cost wins.
  const auto solved = [&](Factors factors) {
    backend::PoseGraph g = jointGraph(robots, factors);
    backend::PoseGraph chordal = g;
    const double from_run = backend::solveCentralized(g, solver).final_cost;
    backend::SolverConfig from_scratch = solver;
    from_scratch.initialisation = "chordal";
    return backend::solveCentralized(chordal, from_scratch).final_cost < from_run ? chordal : g;
  };
  const backend::PoseGraph odometry = solved(Factors::odometry);
  const backend::PoseGraph own_loops = solved(Factors::own_loops);
  const backend::PoseGraph optimum = solved(Factors::joint);
  const backend::PoseGraph exact = solved(Factors::exact);
  std::vector<RobotBound> out;
  for (const RobotGraph& r : robots) {
    out.push_back({r.name, ateOf(r, odometry), ateOf(r, own_loops), ateOf(r, r.graph),
                   ateOf(r, optimum), ateOf(r, exact)});
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

void addBenchBoundCommand(CLI::App& bench) {
  auto o = std::make_shared<BoundOptions>();
  CLI::App* cmd = bench.add_subcommand(
      "bound",
      "how far a run's loops could take its robots: the ATE of the odometry, of each robot's "
      "own SLAM (odometry and its own loops), of the run, of the run's joint graph solved "
      "centrally, and of that graph with every inter-robot loop exact (from the ground truth)");
  cmd->add_option("--run", o->run, "output folder of `dcl-slam run` (one folder per robot)")
      ->required();
  cmd->add_option("--dataset", o->dataset, "the dataset it ran (dataset.yaml), with ground truth")
      ->required();
  cmd->add_flag("--json", o->json, "print the result as JSON");
  cmd->callback([o] { runBound(*o); });
}

}  // namespace dcl::apps
