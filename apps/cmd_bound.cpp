// dcl-slam bench bound and bench noise: see bound.hpp.

#include <algorithm>
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
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include <dcl/backend/centralized_solver.hpp>
#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/error.hpp>
#include <dcl/core/se3.hpp>
#include <dcl/eval/alignment.hpp>
#include <dcl/eval/association.hpp>
#include <dcl/eval/ate.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/io/pose_graph_g2o.hpp>

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
  const backend::PoseGraph all = io::readPoseGraph(folder + "/graph.g2o");
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

/// The robots the run's metrics.json says left mid-run (`left_at_s`); none
/// when the run has no metrics.json (the outputs of `dcl-slam robot`).
std::set<std::string> robotsThatLeft(const std::string& run) {
  const std::string path = run + "/metrics.json";
  if (!std::filesystem::exists(path)) return {};
  const std::vector<char> text = io::readFile(path);
  const Json j = Json::parse(text.begin(), text.end(), nullptr, false);
  if (j.is_discarded() || !j.is_object() || !j.contains("robots") || !j["robots"].is_array())
    throw core::FileError({.path = path}, "not a run's metrics (a JSON object with 'robots')");
  std::set<std::string> left;
  for (const Json& r : j["robots"]) {
    if (!r.is_object() || !r.contains("name") || !r["name"].is_string())
      throw core::FileError({.path = path}, "a robot without a 'name'");
    if (r.contains("left_at_s") && !r["left_at_s"].is_null())
      left.insert(r["name"].get<std::string>());
  }
  return left;
}

/// Every robot of the run in folder `run` of the dataset in folder `dataset`.
std::vector<RobotGraph> readRun(const std::string& run, const std::string& dataset) {
  const io::DatasetSpec spec = io::readDataset(dataset, datasetReadOptions());
  std::vector<RobotGraph> robots;
  for (std::size_t i = 0; i < spec.robots.size(); ++i) {
    if (!std::filesystem::exists(run + "/" + spec.robots[i].name + "/graph.g2o")) {
      throw core::Error("run '" + run + "' has no graph.g2o for robot '" + spec.robots[i].name +
                        "' of dataset '" + dataset + "' (is it the run of that dataset?)");
    }
    robots.push_back(readRobot(run, spec, i));
  }
  return robots;
}

/// The ATE RMSE (m, per-robot SE(3) alignment, as the run's metrics) of
/// robot `r`'s keyframes at the estimates of `graph`; NaN when they cannot be
/// aligned (a robot that has not moved yet).
/// Robot r's keyframes in `graph`, paired with its ground truth.
eval::Association pairsOf(const RobotGraph& r, const backend::PoseGraph& graph) {
  std::vector<Eigen::Isometry3d> poses;
  for (std::size_t k = 0; k < r.stamps.size(); ++k)
    poses.push_back(graph.estimate({r.id, core::KeyframeId(k)}));
  const core::Trajectory estimate(r.stamps, std::move(poses));
  return eval::associateByTimestamp(estimate, r.ground_truth, 0.01);
}

double ateOf(const RobotGraph& r, const backend::PoseGraph& graph) {
  try {
    return eval::computeAte(pairsOf(r, graph), eval::Alignment::se3).translation_m.rmse;
  } catch (const core::Error&) {
    return std::numeric_limits<double>::quiet_NaN();
  }
}

/// Per robot, the lowest robot its accepted inter-robot loops join it to,
/// through any others: the robots whose maps the loops tie into one.
std::vector<std::size_t> loopGroups(const std::vector<RobotGraph>& robots) {
  std::vector<std::size_t> group(robots.size());
  for (std::size_t i = 0; i < robots.size(); ++i) group[i] = i;
  const auto root = [&](std::size_t i) {
    while (group[i] != i) i = group[i];
    return i;
  };
  std::map<core::RobotId, std::size_t> index;
  for (std::size_t i = 0; i < robots.size(); ++i) index[robots[i].id] = i;
  for (const RobotGraph& r : robots) {
    for (const backend::Factor& f : r.graph.factors()) {
      if (f.from.robot == f.to.robot || !index.contains(f.from.robot) ||
          !index.contains(f.to.robot))
        continue;
      const std::size_t a = root(index.at(f.from.robot));
      const std::size_t b = root(index.at(f.to.robot));
      group[std::max(a, b)] = std::min(a, b);
    }
  }
  for (std::size_t i = 0; i < robots.size(); ++i) group[i] = root(i);
  return group;
}

/// Every robot's ATE in `graph` under one SE(3) alignment fitted on the pairs
/// of all robots of its loop group together (as the run's report measures
/// `ate_rmse_joint` over the robots of one frame); NaN for a group whose
/// alignment cannot be fitted.
std::vector<double> jointAteOf(const std::vector<RobotGraph>& robots,
                               const backend::PoseGraph& graph) {
  const std::vector<std::size_t> group = loopGroups(robots);
  std::vector<eval::Association> pairs;
  std::map<std::size_t, eval::Association> all;
  for (std::size_t i = 0; i < robots.size(); ++i) {
    pairs.push_back(pairsOf(robots[i], graph));
    const eval::Association& p = pairs.back();
    eval::Association& mine = all[group[i]];
    for (std::size_t k = 0; k < p.size(); ++k) {
      mine.estimate.push_back(p.estimate.stamp(k), p.estimate.pose(k));
      mine.ground_truth.push_back(p.ground_truth.stamp(k), p.ground_truth.pose(k));
    }
  }
  std::vector<double> out(robots.size(), std::numeric_limits<double>::quiet_NaN());
  for (const auto& [g, together] : all) {
    try {
      const eval::Sim3 S_gt_common = eval::computeAlignment(together, eval::Alignment::se3);
      for (std::size_t i = 0; i < robots.size(); ++i) {
        if (group[i] != g || pairs[i].size() == 0) continue;
        out[i] = eval::computeAte(pairs[i], S_gt_common, eval::Alignment::se3).translation_m.rmse;
      }
    } catch (const core::Error&) {
    }
  }
  return out;
}

/// The errors of one class of factors (or of odometry compounded over a
/// span of keyframes) against the ground truth, beside their covariances.
struct NoiseRow {
  std::string factors;
  std::size_t count = 0;
  /// Per axis of the factor's frame (x y z, then rotations about them): sums
  /// of squared errors and of variances (m^2, rad^2).
  core::Vector6d error_axes = core::Vector6d::Zero();
  core::Vector6d sigma_axes = core::Vector6d::Zero();
  double nees = 0.0;  ///< sum of r^T Omega r

  void add(const core::Vector6d& r, const core::Matrix6d& covariance) {
    ++count;
    error_axes += r.cwiseAbs2();
    sigma_axes += covariance.diagonal();
    nees += r.dot(covariance.ldlt().solve(r));
  }
  /// The root of a sum's mean over the factors.
  [[nodiscard]] double rms(double sum) const {
    return count == 0 ? 0.0 : std::sqrt(sum / static_cast<double>(count));
  }
  [[nodiscard]] core::Vector6d rms(const core::Vector6d& sums) const {
    return count == 0 ? core::Vector6d::Zero()
                      : core::Vector6d((sums / static_cast<double>(count)).cwiseSqrt());
  }
  /// RMS of the translation (first) or rotation error's norm, and of the
  /// root of the covariance block's trace.
  [[nodiscard]] double errorRms(int block) const {
    return rms(error_axes.segment<3>(3 * block).sum());
  }
  [[nodiscard]] double sigmaRms(int block) const {
    return rms(sigma_axes.segment<3>(3 * block).sum());
  }
  [[nodiscard]] double neesPerDof() const {
    return count == 0 ? 0.0 : nees / (6.0 * static_cast<double>(count));
  }
};

core::Matrix6d covarianceOf(const backend::Factor& f) {
  return f.information.ldlt().solve(core::Matrix6d::Identity());
}

/// The residual of a measurement T_from_to (as the solvers define it: log(T_from_to^-1 T_from^-1
/// T_to) in [rho; phi]) at the ground truth.
core::Vector6d trueResidual(const Eigen::Isometry3d& T_from_to,
                            const Eigen::Isometry3d& T_world_from,
                            const Eigen::Isometry3d& T_world_to) {
  return core::logSE3(T_from_to.inverse() * T_world_from.inverse() * T_world_to);
}

/// Every robot's odometry compounded over `span` keyframes (windows half a span
/// apart; covariances propagated as the keyframe selector does), then the own
/// and the inter-robot loops, once each.
std::vector<NoiseRow> factorNoise(const std::vector<RobotGraph>& robots,
                                  const std::vector<std::size_t>& spans) {
  std::vector<NoiseRow> rows;
  for (const std::size_t span : spans) {
    NoiseRow row{fmt::format("odometry, {} keyframe{}", span, span == 1 ? "" : "s")};
    for (const RobotGraph& r : robots) {
      std::map<std::size_t, const backend::Factor*> chain;  ///< by the keyframe it starts at
      for (const backend::Factor& f : r.graph.factors()) {
        if (f.kind == backend::FactorKind::odometry && f.from.robot == r.id && f.to.robot == r.id &&
            f.to.keyframe.value() == f.from.keyframe.value() + 1)
          chain[f.from.keyframe.value()] = &f;
      }
      const std::size_t step = std::max<std::size_t>(1, span / 2);
      for (std::size_t first = 0; first + span < r.T_world_gt.size(); first += step) {
        Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
        core::Matrix6d covariance = core::Matrix6d::Zero();
        bool whole = true;
        for (std::size_t k = first; k < first + span; ++k) {
          const auto it = chain.find(k);
          if (it == chain.end()) {
            whole = false;
            break;
          }
          const core::Matrix6d Ad = core::adjoint(it->second->T_from_to.inverse());
          covariance = Ad * covariance * Ad.transpose() + covarianceOf(*it->second);
          T = T * it->second->T_from_to;
        }
        if (!whole) continue;
        row.add(trueResidual(T, r.T_world_gt[first], r.T_world_gt[first + span]), covariance);
      }
    }
    rows.push_back(row);
  }
  std::map<core::RobotId, const RobotGraph*> by_id;
  for (const RobotGraph& r : robots) by_id[r.id] = &r;
  NoiseRow intra{"own loops"};
  NoiseRow inter{"inter-robot loops"};
  std::set<std::pair<core::PoseKey, core::PoseKey>> seen;
  for (const RobotGraph& r : robots) {
    for (const backend::Factor& f : r.graph.factors()) {
      if (f.kind == backend::FactorKind::odometry) continue;
      if (f.from.robot == f.to.robot && f.from.robot != r.id) continue;
      if (!by_id.contains(f.from.robot) || !by_id.contains(f.to.robot)) continue;
      if (!seen.insert(std::minmax(f.from, f.to)).second) continue;
      const RobotGraph& a = *by_id.at(f.from.robot);
      const RobotGraph& b = *by_id.at(f.to.robot);
      const std::size_t i = f.from.keyframe.value(), j = f.to.keyframe.value();
      if (i >= a.T_world_gt.size() || j >= b.T_world_gt.size()) continue;
      (f.from.robot == f.to.robot ? intra : inter)
          .add(trueResidual(f.T_from_to, a.T_world_gt[i], b.T_world_gt[j]), covarianceOf(f));
    }
  }
  rows.push_back(intra);
  rows.push_back(inter);
  return rows;
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
  JointCosts costs;
  const std::vector<RobotBound> robots = computeBound(o.run, o.dataset, &costs);
  const std::vector<std::pair<const char*, double RobotBound::*>> columns{
      {"odometry", &RobotBound::odometry},
      {"own_loops", &RobotBound::own_loops},
      {"run", &RobotBound::run},
      {"optimum", &RobotBound::optimum},
      {"exact", &RobotBound::exact}};
  const std::vector<std::pair<const char*, double RobotBound::*>> joint_columns{
      {"run", &RobotBound::run_joint},
      {"optimum", &RobotBound::optimum_joint},
      {"exact", &RobotBound::exact_joint}};
  const auto cell = [](double value) {
    return std::isnan(value) ? std::string("-") : fmt::format("{:.4f}", value);
  };
  if (o.json) {
    Json out{{"run", o.run},
             {"dataset", o.dataset},
             {"cost_run", costs.run},
             {"cost_optimum", costs.optimum},
             {"left", costs.left},
             {"cost_run_stayed", costs.stayed_run},
             {"cost_optimum_stayed", costs.stayed_optimum},
             {"robots", Json::array()}};
    for (const RobotBound& r : robots) {
      Json j{{"name", r.name}, {"left", r.left}};
      for (const auto& [key, field] : columns) j[std::string("ate_") + key] = r.*field;
      for (const auto& [key, field] : joint_columns) j[std::string("ate_joint_") + key] = r.*field;
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
    fmt::print("{:<10}", r.left ? r.name + " (left)" : r.name);
    for (const auto& [key, field] : columns) fmt::print("{:>12}", cell(r.*field));
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
  fmt::print(
      "\n\nATE (m) per robot under one alignment for all the robots its loops join it to (the "
      "merged map: how well the robots' frames agree)\n");
  fmt::print("{:<10}{:>12}{:>12}{:>12}\n", "robot", "the run", "optimum", "loops exact");
  for (const RobotBound& r : robots) {
    fmt::print("{:<10}", r.name);
    for (const auto& [key, field] : joint_columns) fmt::print("{:>12}", cell(r.*field));
    fmt::print("\n");
  }
  fmt::print("\nJoint graph's chi-square: the run {:.6g}, the optimum {:.6g}", costs.run,
             costs.optimum);
  if (costs.optimum > 0.0) fmt::print(" ({:.3f} times)", costs.run / costs.optimum);
  fmt::print("\n");
  if (costs.left.empty()) return;
  fmt::print("Without the robots that left ({}): the run {:.6g}, the optimum {:.6g}",
             fmt::join(costs.left, " "), costs.stayed_run, costs.stayed_optimum);
  if (costs.stayed_optimum > 0.0)
    fmt::print(" ({:.3f} times)", costs.stayed_run / costs.stayed_optimum);
  fmt::print("\n");
}

/// x y z (m) and roll pitch yaw (rad) as a JSON array.
Json axes(const core::Vector6d& v) {
  return Json(std::vector<double>(v.data(), v.data() + 6));
}

void runNoise(const BoundOptions& o) {
  const std::vector<RobotGraph> robots = readRun(o.run, o.dataset);
  const std::vector<NoiseRow> rows = factorNoise(robots, {1, 10, 100});
  if (o.json) {
    Json out{{"run", o.run}, {"dataset", o.dataset}, {"factors", Json::array()}};
    for (const NoiseRow& r : rows) {
      out["factors"].push_back({{"factors", r.factors},
                                {"count", r.count},
                                {"error_t_m", r.errorRms(0)},
                                {"sigma_t_m", r.sigmaRms(0)},
                                {"error_r_rad", r.errorRms(1)},
                                {"sigma_r_rad", r.sigmaRms(1)},
                                {"nees_per_dof", r.neesPerDof()},
                                {"error_axes", axes(r.rms(r.error_axes))},
                                {"sigma_axes", axes(r.rms(r.sigma_axes))}});
    }
    fmt::print("{}\n", out.dump(2));
    return;
  }
  fmt::print(
      "Factors against the ground truth: RMS error and RMS standard deviation (root of the "
      "covariance's trace), translation and rotation; NEES per degree of freedom (1: the "
      "covariances describe the errors; below: too loose; above: too tight)\n");
  fmt::print("{:<24}{:>7}{:>11}{:>11}{:>13}{:>13}{:>9}\n", "factors", "count", "error (m)",
             "sigma (m)", "error (mrad)", "sigma (mrad)", "NEES/dof");
  for (const NoiseRow& r : rows) {
    fmt::print("{:<24}{:>7}", r.factors, r.count);
    if (r.count == 0) {
      fmt::print("\n");
      continue;
    }
    fmt::print("{:>11.4f}{:>11.4f}{:>13.3f}{:>13.3f}{:>9.3f}\n", r.errorRms(0), r.sigmaRms(0),
               1e3 * r.errorRms(1), 1e3 * r.sigmaRms(1), r.neesPerDof());
  }
  fmt::print(
      "\nPer axis of the factor's frame (the sensor's: x forward, y left, z up when level): RMS "
      "error / RMS standard deviation, cm and mrad\n");
  fmt::print("{:<24}", "factors");
  for (const char* axis : {"x", "y", "z", "roll", "pitch", "yaw"}) fmt::print("{:>15}", axis);
  fmt::print("\n");
  for (const NoiseRow& r : rows) {
    if (r.count == 0) continue;
    fmt::print("{:<24}", r.factors);
    const core::Vector6d error = r.rms(r.error_axes);
    const core::Vector6d sigma = r.rms(r.sigma_axes);
    for (int k = 0; k < 6; ++k) {
      const double unit = k < 3 ? 1e2 : 1e3;
      fmt::print("{:>15}", fmt::format("{:.2f} / {:.2f}", unit * error(k), unit * sigma(k)));
    }
    fmt::print("\n");
  }
}

}  // namespace

std::vector<RobotBound> computeBound(const std::string& run, const std::string& dataset,
                                     JointCosts* costs) {
  const std::vector<RobotGraph> robots = readRun(run, dataset);
  const std::set<std::string> left = robotsThatLeft(run);
  backend::SolverConfig solver;
  solver.max_iterations = 200;
  // From the run's estimates, and from the chordal initialisation: a run whose
  // robots ended in frames of different rounds is a poor start, and
  // Levenberg-Marquardt can settle in a local minimum from it. The lower cost wins.
  const auto solved = [&](Factors factors, const std::vector<RobotGraph>& of) {
    backend::PoseGraph g = jointGraph(of, factors);
    backend::PoseGraph chordal = g;
    const double from_run = backend::solveCentralized(g, solver).final_cost;
    backend::SolverConfig from_scratch = solver;
    from_scratch.initialisation = "chordal";
    return backend::solveCentralized(chordal, from_scratch).final_cost < from_run ? chordal : g;
  };
  const backend::PoseGraph odometry = solved(Factors::odometry, robots);
  const backend::PoseGraph own_loops = solved(Factors::own_loops, robots);
  const backend::PoseGraph optimum = solved(Factors::joint, robots);
  const backend::PoseGraph exact = solved(Factors::exact, robots);
  if (costs != nullptr) {
    *costs = JointCosts{};
    costs->run = backend::graphCost(jointGraph(robots, Factors::joint));
    costs->optimum = backend::graphCost(optimum);
    std::vector<RobotGraph> stayed;
    for (const RobotGraph& r : robots) {
      if (left.contains(r.name))
        costs->left.push_back(r.name);
      else
        stayed.push_back(r);
    }
    if (!costs->left.empty() && !stayed.empty()) {
      costs->stayed_run = backend::graphCost(jointGraph(stayed, Factors::joint));
      costs->stayed_optimum = backend::graphCost(solved(Factors::joint, stayed));
    }
  }
  backend::PoseGraph run_graph;  ///< every robot's own keyframes where the run left them
  for (const RobotGraph& r : robots)
    for (const auto& [key, T] : r.graph.nodes()) run_graph.addNode(key, T);
  const std::vector<double> run_joint = jointAteOf(robots, run_graph);
  const std::vector<double> optimum_joint = jointAteOf(robots, optimum);
  const std::vector<double> exact_joint = jointAteOf(robots, exact);
  std::vector<RobotBound> out;
  for (std::size_t i = 0; i < robots.size(); ++i) {
    const RobotGraph& r = robots[i];
    out.push_back({r.name, ateOf(r, odometry), ateOf(r, own_loops), ateOf(r, r.graph),
                   ateOf(r, optimum), ateOf(r, exact), run_joint[i], optimum_joint[i],
                   exact_joint[i], left.contains(r.name)});
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
  // Both read a run's outputs beside its dataset.
  const auto add = [&bench](const char* name, const char* help,
                            void (*command)(const BoundOptions&)) {
    auto o = std::make_shared<BoundOptions>();
    CLI::App* cmd = bench.add_subcommand(name, help);
    cmd->add_option("--run", o->run, "output folder of `dcl-slam run` (one folder per robot)")
        ->required();
    cmd->add_option("--dataset", o->dataset, "the dataset it ran (dataset.yaml), with ground truth")
        ->required();
    cmd->add_flag("--json", o->json, "print the result as JSON");
    cmd->callback([o, command] { command(*o); });
  };
  add("bound",
      "how far a run's loops could take its robots: the ATE of the odometry, of each robot's "
      "own SLAM (odometry and its own loops), of the run, of the run's joint graph solved "
      "centrally, and of that graph with every inter-robot loop exact (from the ground truth)",
      runBound);
  add("noise",
      "how well a run's factor covariances describe their errors: each robot's odometry over "
      "1, 10 and 100 keyframes, its own loops and the inter-robot loops, against the ground truth",
      runNoise);
}

}  // namespace dcl::apps
