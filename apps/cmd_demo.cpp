// `dcl-slam demo`: the built-in default run, no arguments needed. Simulates the
// `demo` preset (three cars on loops around city blocks, VLP-16, with moving
// traffic), runs the whole swarm over the simulated radio as `dcl-slam run`
// does, prints a table per robot (ATE by odometry alone and with
// collaboration, the cut, loops, bytes sent) and writes the outputs: the
// dataset and its preview, trajectories, graphs, the merged map, metrics.json
// and report.html.
#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/core/error.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/sim/presets.hpp>
#include <dcl/sim/preview.hpp>
#include <dcl/sim/sim_source.hpp>
#include <dcl/sim/traffic.hpp>
#include <dcl/swarm/swarm_run.hpp>

#include "commands.hpp"
#include "output_folder.hpp"
#include "printing.hpp"
#include "robot_outputs.hpp"
#include "run_swarm.hpp"

namespace dcl::apps {
namespace {

using Json = nlohmann::ordered_json;

struct DemoOptions {
  std::string out = "out/demo";  ///< where results go
  int threads = 0;               ///< robots processed at once (0: every core)
  bool force = false;            ///< replace --out even when it holds files of another program
  VizOptions viz;                ///< served live to Foxglove
};

/// The demo's street traffic: a KITTI-like city street's (`simulate --traffic 1`).
constexpr double kDemoTraffic = 1.0;

/// The preset's dataset (ground truth only: scans are regenerated) and its
/// preview, written into `out` (which will be `shown`).
std::string simulate(const std::string& out, const std::string& shown) {
  const std::string folder = out + "/dataset";
  const io::DatasetSpec spec =
      sim::writeSimDataset(folder, sim::makePreset("demo"), {.traffic = kDemoTraffic});
  const sim::SimWorld world(spec);
  std::vector<core::Trajectory> routes;
  for (std::size_t r = 0; r < world.robots(); ++r) routes.push_back(world.groundTruth(r));
  const sim::Traffic& traffic = world.simulator().traffic();
  sim::writeWorldPreview(world.world(), routes, out + "/preview_world.png", {}, &traffic);
  fmt::print(
      "simulated the 'demo' preset: {} cars on city loops, {} triangles, {} moving cars, cyclists "
      "and pedestrians; dataset in {}/dataset\n",
      world.robots(), world.world().triangleCount(),
      traffic.count(sim::ActorKind::car) + traffic.count(sim::ActorKind::cyclist) +
          traffic.count(sim::ActorKind::pedestrian),
      shown);
  return folder;
}

/// How much lower the ATE with collaboration is than by odometry alone, "22 %"
/// ("-27 %": higher), or "-" without both.
std::string cut(const Json& r) {
  const Json& odometry = r["ate_rmse_odometry_only"];
  const Json& collaboration = r["ate_rmse"];
  if (odometry.is_null() || collaboration.is_null() || !(odometry.get<double>() > 0.0)) return "-";
  return fmt::format("{:.0f} %",
                     100.0 * (1.0 - collaboration.get<double>() / odometry.get<double>()));
}

void printTable(const Json& m) {
  fmt::print("\n{:<6} {:>10} {:>12} {:>6} {:>10} {:>12} {:>9}\n", "robot", "ATE odom", "ATE collab",
             "cut", "ATE joint", "loops kept", "kB sent");
  for (const Json& r : m["robots"]) {
    fmt::print("{:<6} {:>10} {:>12} {:>6} {:>10} {:>12} {:>9.1f}\n", r["name"].get<std::string>(),
               metresText(r["ate_rmse_odometry_only"]), metresText(r["ate_rmse"]), cut(r),
               metresText(r["ate_rmse_joint"]),
               fmt::format("{} + {}", r["intra_loops"].get<std::size_t>(),
                           r["inter_loops_accepted"].get<std::size_t>()),
               static_cast<double>(r["bytes_sent"].get<std::size_t>()) / 1000.0);
  }
  printFrames(m);
  fmt::print(
      "ATE in m (keyframes, SE(3)-aligned per robot; joint: one alignment for all robots of a "
      "frame); cut: ATE collab below ATE odom; loops: intra + inter-robot\n");
}

void runDemo(const DemoOptions& o, const AppConfig& config) {
  OutputFolder out(o.out, o.force);
  const std::string dataset = simulate(out.path(), out.out());
  const Json metrics = runSwarmDataset(dataset, out.path(), 0, o.threads,
                                       swarm::SwarmConfig{}.settle, config, {}, o.viz);
  out.commit();
  printTable(metrics);
  fmt::print("outputs in {}: report.html, {}metrics.json, one folder per robot\n", o.out,
             metrics["map_points"].get<std::size_t>() > 0 ? "map.ply (robots coloured), " : "");
}

}  // namespace

void addDemoCommand(CLI::App& app, const AppConfig& config) {
  auto* cmd = app.add_subcommand(
      "demo",
      "the built-in default run: simulates three cars driving loops in a city with traffic and "
      "runs them over the simulated radio (no arguments needed)");
  auto o = std::make_shared<DemoOptions>();
  cmd->add_option("--out", o->out, "output folder")->capture_default_str();
  cmd->add_option("--threads", o->threads, "robots processed at once (0: every core)")
      ->capture_default_str();
  addForceFlag(*cmd, o->force);
  addVizOptions(*cmd, o->viz);
  cmd->callback([o, &config] {
    if (o->threads < 0) throw core::Error("--threads must be at least 0");
    runDemo(*o, config);
  });
}

}  // namespace dcl::apps
