// dcl-slam bench bound and bench noise: the run's outputs read
// (run_graphs.hpp), evaluated (eval/bound.hpp, eval/factor_noise.hpp) and printed.

#include <cmath>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <CLI/CLI.hpp>
#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include <dcl/core/se3.hpp>
#include <dcl/eval/bound.hpp>
#include <dcl/eval/factor_noise.hpp>

#include "commands.hpp"
#include "run_graphs.hpp"

namespace dcl::apps {
namespace {

using Json = nlohmann::ordered_json;
using eval::meanLowered;
using eval::notBelow;
using eval::RobotBound;

struct BoundOptions {
  std::string run;
  std::string dataset;
  bool json = false;
};

void runBound(const BoundOptions& o) {
  std::vector<eval::RobotGraph> graphs = readRunGraphs(o.run, o.dataset);
  readRobotsThatLeft(o.run, graphs);
  eval::JointCosts costs;
  const std::vector<RobotBound> robots = eval::computeBound(graphs, &costs);
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
  const std::vector<eval::FactorNoise> rows =
      eval::factorNoise(readRunGraphs(o.run, o.dataset), {1, 10, 100});
  if (o.json) {
    Json out{{"run", o.run}, {"dataset", o.dataset}, {"factors", Json::array()}};
    for (const eval::FactorNoise& r : rows) {
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
  for (const eval::FactorNoise& r : rows) {
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
  for (const eval::FactorNoise& r : rows) {
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
