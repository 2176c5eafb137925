// `dcl-slam bench system`: the paper's experiments (§IV) on simulated
// datasets. Each dataset is simulated from its preset (once; the folder is
// reused), run with every robot in one process over the simulated radio as
// `dcl-slam run` does, and summarised as the paper's tables: ATE and ARE per
// robot with odometry only and with the whole system (Tables II, III),
// transmitted data per robot and communication time (Table IV), the sizes of
// the messages sent (Table V), and the large-team run (§IV-E: average ATE,
// transmit and receive rates).
//
// The paper assumes no communication range limit for these experiments ("messages
// can be exchanged at any time"); so does this bench unless --range is given.
//
// One seed is one simulated world per preset: its city or campus, the noise
// of its routes and its LiDAR units' calibration errors. --seeds runs every
// preset in several and adds a table across them, so that a method is judged
// on more than the one draw the presets' default seed makes.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/core/error.hpp>
#include <dcl/eval/bound.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/file.hpp>
#include <dcl/sim/presets.hpp>
#include <dcl/sim/sim_source.hpp>
#include <dcl/swarm/swarm_run.hpp>

#include "commands.hpp"
#include "option_checks.hpp"
#include "run_graphs.hpp"
#include "run_swarm.hpp"

namespace dcl::apps {
namespace {

namespace fs = std::filesystem;
using Json = nlohmann::ordered_json;
using eval::meanLowered;
using eval::notBelow;
using eval::RobotBound;

// The paper's average transmit rates per robot (Table IV and §IV-E), kB/s.
constexpr double kPaperKittiTransmit = 164.67;
constexpr double kPaperCampusTransmit = 53.55;
constexpr double kPaperLargeTeamTransmit = 34.36;
constexpr double kPaperLargeTeamReceive = 193.57;

struct SystemOptions {
  std::vector<std::string> datasets{"kitti05-3", "kitti08-2", "kitti00-3", "campus-3"};
  std::string scale = "campus-9";  ///< the large-team preset ("none": skip)
  int scale_robots = 0;            ///< robots of the large-team run (0: the preset's)
  /// Worlds to simulate each preset in (one city or campus, routes and sensor
  /// units per seed); every preset is run once per seed.
  std::vector<std::uint64_t> seeds{1};
  std::string work = "out/bench-system";
  std::string data;  ///< the shared data folder (KITTI ground truth)
  std::size_t max_frames = 0;
  int threads = 0;
  double settle = swarm::SwarmConfig{}.settle;  ///< s at most after the data while robots optimise
  double range = 0.0;        ///< m, the radio's range (0: unlimited, as in the paper)
  double traffic = 0.0;      ///< moving actors, times each world's own traffic (0: none)
  bool body_motion = false;  ///< generated routes' vehicles rock on their suspension
  std::string markdown;      ///< where to write the tables as Markdown too
  bool json = false;
};

/// The dataset of `preset` in `folder`, simulated unless it is already there.
std::string ensureDataset(const std::string& preset, int robots, std::uint64_t seed,
                          const SystemOptions& o, const std::string& folder) {
  if (fs::exists(fs::path(folder) / "dataset.yaml")) return folder;
  sim::writeSimDataset(
      folder,
      sim::makePreset(
          preset,
          {.data_dir = o.data, .seed = seed, .robots = robots, .body_motion = o.body_motion}),
      {.traffic = o.traffic});
  return folder;
}

/// The name of a preset's run in `seed`'s world: the preset's own for seed 1
/// (the presets' default), "<preset>-s<seed>" for the others, and
/// "-t<density>" after it with traffic and "-b" with the vehicles' body
/// motion, so that each kind of world keeps its own folders.
std::string runName(const std::string& preset, std::uint64_t seed, const SystemOptions& o) {
  std::string name = seed == 1 ? preset : fmt::format("{}-s{}", preset, seed);
  if (o.traffic > 0.0) name += fmt::format("-t{:g}", o.traffic);
  if (o.body_motion) name += "-b";
  return name;
}

std::optional<double> number(const Json& value) {
  if (value.is_null()) return std::nullopt;
  return value.get<double>();
}

std::string cell(const std::optional<double>& value, const char* format = "{:.3f}") {
  return value ? fmt::format(fmt::runtime(format), *value) : "-";
}

/// 1 - full / odometry-only, when both are known.
std::optional<double> improvement(const Json& robot, const char* full, const char* odometry) {
  const auto f = number(robot[full]);
  const auto o = number(robot[odometry]);
  if (!f || !o || *o <= 0.0) return std::nullopt;
  return 1.0 - *f / *o;
}

/// A fraction as a whole percentage, "-0 %" written as "0 %".
std::string percent(double fraction) {
  const double rounded = std::round(100.0 * fraction);
  return fmt::format("{:.0f} %", rounded == 0.0 ? 0.0 : rounded);
}

double mean(const std::vector<double>& v) {
  double sum = 0.0;
  for (double x : v) sum += x;
  return v.empty() ? 0.0 : sum / static_cast<double>(v.size());
}

struct DatasetRun {
  std::string name;
  std::string preset;
  std::uint64_t seed = 1;
  Json metrics;
  double seconds = 0.0;           ///< wall time of the run
  std::vector<RobotBound> bound;  ///< own SLAM, joint optimum and exact loops (eval/bound.hpp)
};

/// The bound tables: what each robot's own loops, the system, the joint
/// optimum and exact loops make of its ATE.
std::string boundTables(const std::vector<const DatasetRun*>& runs) {
  std::ostringstream out;
  out << "\nOwn SLAM and bound (`dcl-slam bench bound`): ATE [m] per robot of its odometry, its "
         "own SLAM (odometry and its own loops, solved: single-robot SLAM, the paper's \"only "
         "LIO-SAM\"), the system, the run's joint graph solved centrally, and that graph with "
         "every inter-robot loop exact\n\n"
         "| dataset | robot | odometry | own SLAM | system | joint optimum | loops exact |\n"
         "|---|---|---|---|---|---|---|\n";
  for (const DatasetRun* run : runs) {
    for (const RobotBound& r : run->bound) {
      const auto m = [](double v) { return std::isnan(v) ? "-" : fmt::format("{:.3f}", v); };
      out << fmt::format("| `{}` | {} | {} | {} | {} | {} | {} |\n", run->name, r.name,
                         m(r.odometry), m(r.own_loops), m(r.run), m(r.optimum), m(r.exact));
    }
  }
  out << "\nPer dataset: ATE lowered on average against the odometry, and against each "
         "robot's own SLAM (robots not below it)\n\n"
         "| dataset | own SLAM vs odometry | system vs odometry | system vs own SLAM | joint "
         "optimum vs own SLAM | loops exact vs own SLAM |\n|---|---|---|---|---|---|\n";
  for (const DatasetRun* run : runs) {
    const auto& b = run->bound;
    const auto vsOwn = [&](double RobotBound::*value) {
      return fmt::format("{} ({} of {} not below)",
                         percent(meanLowered(b, value, &RobotBound::own_loops)),
                         notBelow(b, value, &RobotBound::own_loops), b.size());
    };
    out << fmt::format("| `{}` | {} | {} | {} | {} | {} |\n", run->name,
                       percent(meanLowered(b, &RobotBound::own_loops, &RobotBound::odometry)),
                       percent(meanLowered(b, &RobotBound::run, &RobotBound::odometry)),
                       vsOwn(&RobotBound::run), vsOwn(&RobotBound::optimum),
                       vsOwn(&RobotBound::exact));
  }
  return out.str();
}

/// The run's per-dataset summary: averages over its robots.
Json summaryOf(const DatasetRun& run) {
  std::vector<double> gain, ate, transmit, receive;
  std::size_t kept_ends = 0, wrong = 0;
  for (const Json& r : run.metrics["robots"]) {
    kept_ends += r["inter_loops_accepted"].get<std::size_t>();
    if (const auto w = number(r["inter_loops_accepted_wrong"]))
      wrong += static_cast<std::size_t>(*w);
    if (const auto g = improvement(r, "ate_rmse", "ate_rmse_odometry_only")) gain.push_back(*g);
    if (const auto a = number(r["ate_rmse"])) ate.push_back(*a);
    transmit.push_back(r["transmit_kBps"].get<double>());
    receive.push_back(r["receive_kBps"].get<double>());
  }
  return {{"dataset", run.name},
          {"preset", run.preset},
          {"seed", run.seed},
          {"robots", run.metrics["robots"].size()},
          {"wall_s", run.seconds},
          {"duration_s", run.metrics["duration_s"]},
          {"ate_rmse_mean", mean(ate)},
          {"ate_improvement_mean", mean(gain)},
          {"transmit_kBps_mean", mean(transmit)},
          {"receive_kBps_mean", mean(receive)},
          {"inter_loops_kept", kept_ends / 2},  // each loop is held by both its robots
          {"inter_loops_kept_wrong", wrong}};
}

bool isKitti(const std::string& name) {
  return name.rfind("kitti", 0) == 0;
}

/// Per preset over its seeds' worlds: the ATE lowered against the odometry
/// by the system and by the joint optimum of its graph, and the robots left
/// above their odometry.
std::string seedsTable(const std::vector<const DatasetRun*>& runs) {
  std::ostringstream out;
  out << "\nAcross seeds (each preset simulated in several worlds: its city or campus, its "
         "routes' noise and its LiDAR units): mean ATE lowered against the odometry per seed, "
         "their mean, and the robots not below their odometry\n\n"
         "| preset | seeds | system, per seed | system, mean | robots not below | joint optimum, "
         "mean | robots not below at the optimum | inter-robot loops kept (wrong) |\n"
         "|---|---|---|---|---|---|---|---|\n";
  std::vector<std::string> presets;
  for (const DatasetRun* run : runs) {
    if (std::find(presets.begin(), presets.end(), run->preset) == presets.end())
      presets.push_back(run->preset);
  }
  std::size_t total_runs = 0, total_robots = 0, total_above = 0, total_kept = 0, total_wrong = 0;
  for (const std::string& preset : presets) {
    std::vector<double> system, optimum;
    std::string per_seed;
    std::size_t robots = 0, above = 0, above_optimum = 0, kept = 0, wrong = 0;
    for (const DatasetRun* run : runs) {
      if (run->preset != preset) continue;
      const Json s = summaryOf(*run);
      kept += s["inter_loops_kept"].get<std::size_t>();
      wrong += s["inter_loops_kept_wrong"].get<std::size_t>();
      const auto& b = run->bound;
      system.push_back(meanLowered(b, &RobotBound::run, &RobotBound::odometry));
      optimum.push_back(meanLowered(b, &RobotBound::optimum, &RobotBound::odometry));
      per_seed += fmt::format("{}{}", per_seed.empty() ? "" : " / ", percent(system.back()));
      robots += b.size();
      above += notBelow(b, &RobotBound::run, &RobotBound::odometry);
      above_optimum += notBelow(b, &RobotBound::optimum, &RobotBound::odometry);
    }
    out << fmt::format("| `{}` | {} | {} | {} | {} of {} | {} | {} of {} | {} ({}) |\n", preset,
                       system.size(), per_seed, percent(mean(system)), above, robots,
                       percent(mean(optimum)), above_optimum, robots, kept, wrong);
    total_runs += system.size();
    total_robots += robots;
    total_above += above;
    total_kept += kept;
    total_wrong += wrong;
  }
  out << fmt::format(
      "\n{} runs: {} of {} robots not below their odometry; {} inter-robot loops kept, {} of "
      "them wrong\n",
      total_runs, total_above, total_robots, total_kept, total_wrong);
  return out.str();
}

/// Tables II/III (accuracy), IV (bandwidth) and the large-team summary, in Markdown.
std::string tables(const std::vector<DatasetRun>& runs, const std::vector<DatasetRun>& scales,
                   bool across_seeds) {
  std::ostringstream out;
  out << "Accuracy (paper Tables II, III): ATE [m] and ARE [deg] per robot, odometry only -> "
         "whole system\n\n"
         "| dataset | robot | ATE odometry | ATE system | change | ARE odometry | ARE system |\n"
         "|---|---|---|---|---|---|---|\n";
  for (const DatasetRun& run : runs) {
    for (const Json& r : run.metrics["robots"]) {
      const auto gain = improvement(r, "ate_rmse", "ate_rmse_odometry_only");
      out << fmt::format(
          "| `{}` | {} | {} | {} | {} | {} | {} |\n", run.name, r["name"].get<std::string>(),
          cell(number(r["ate_rmse_odometry_only"])), cell(number(r["ate_rmse"])),
          gain ? fmt::format("{:+.0f} %", -100.0 * *gain) : "-",
          cell(number(r["are_rmse_deg_odometry_only"])), cell(number(r["are_rmse_deg"])));
    }
  }
  out << "\nPer dataset (ATE lowered on average by; the target is at least 30 %):\n\n"
         "| dataset | robots | mean ATE system | mean ATE lowered by | run wall time | simulated "
         "time |\n|---|---|---|---|---|---|\n";
  for (const DatasetRun& run : runs) {
    const Json s = summaryOf(run);
    out << fmt::format("| `{}` | {} | {:.3f} m | {} | {:.0f} s | {:.0f} s |\n", run.name,
                       s["robots"].get<std::size_t>(), s["ate_rmse_mean"].get<double>(),
                       percent(s["ate_improvement_mean"].get<double>()), run.seconds,
                       s["duration_s"].get<double>());
  }
  out << "\nBandwidth (paper Table IV): average transmitted data per robot [kB/s] and "
         "communication time (the run's simulated duration)\n\n"
         "| dataset | per robot | average | paper's average | ratio | receive average | "
         "communication time |\n|---|---|---|---|---|---|---|\n";
  for (const DatasetRun& run : runs) {
    std::string per_robot;
    for (const Json& r : run.metrics["robots"])
      per_robot +=
          fmt::format("{}{:.1f}", per_robot.empty() ? "" : " / ", r["transmit_kBps"].get<double>());
    const Json s = summaryOf(run);
    const double paper = isKitti(run.name) ? kPaperKittiTransmit : kPaperCampusTransmit;
    const double transmit = s["transmit_kBps_mean"].get<double>();
    out << fmt::format("| `{}` | {} | {:.1f} | {:.2f} | 1/{:.1f} | {:.1f} | {:.0f} s |\n", run.name,
                       per_robot, transmit, paper, paper / transmit,
                       s["receive_kBps_mean"].get<double>(), s["duration_s"].get<double>());
  }
  std::vector<const DatasetRun*> all;
  for (const DatasetRun& run : runs) all.push_back(&run);
  for (const DatasetRun& run : scales) all.push_back(&run);
  out << boundTables(all);
  if (!scales.empty()) {
    out << fmt::format(
        "\nLarge team (paper §IV-E, 9 robots: ATE 1.83 m, transmit {:.2f} kB/s, receive {:.2f} "
        "kB/s)\n\n| dataset | robots | mean ATE system | mean ATE lowered by | transmit kB/s "
        "| receive kB/s | run wall time |\n|---|---|---|---|---|---|---|\n",
        kPaperLargeTeamTransmit, kPaperLargeTeamReceive);
    for (const DatasetRun& scale : scales) {
      const Json s = summaryOf(scale);
      out << fmt::format("| `{}` | {} | {:.3f} m | {} | {:.1f} | {:.1f} | {:.0f} s |\n", scale.name,
                         s["robots"].get<std::size_t>(), s["ate_rmse_mean"].get<double>(),
                         percent(s["ate_improvement_mean"].get<double>()),
                         s["transmit_kBps_mean"].get<double>(),
                         s["receive_kBps_mean"].get<double>(), scale.seconds);
    }
  }
  if (across_seeds) out << seedsTable(all);
  return out.str();
}

DatasetRun runOne(const std::string& preset, int robots, std::uint64_t seed,
                  const std::string& name, const SystemOptions& o, const AppConfig& config) {
  const std::string folder =
      ensureDataset(preset, robots, seed, o, (fs::path(o.work) / name).string());
  AppConfig c = config;
  c.radio.range = o.range;
  const auto start = std::chrono::steady_clock::now();
  Json metrics = runSwarmDataset(folder, (fs::path(o.work) / (name + "-run")).string(),
                                 o.max_frames, o.threads, o.settle, c);
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  DatasetRun run{name, preset, seed, std::move(metrics), seconds, {}};
  const std::string run_folder = (fs::path(o.work) / (name + "-run")).string();
  std::vector<eval::RobotGraph> graphs = readRunGraphs(run_folder, folder);
  readRobotsThatLeft(run_folder, graphs);
  run.bound = eval::computeBound(graphs);
  return run;
}

void runSystem(const SystemOptions& o, const AppConfig& config) {
  if (o.threads < 0) throw core::Error("--threads must be at least 0");
  if (!(o.range >= 0.0)) throw core::Error("--range must be zero (unlimited) or positive");
  if (o.seeds.empty()) throw core::Error("--seeds needs at least one seed");
  if (!(o.traffic >= 0.0 && o.traffic <= 10.0))
    throw core::Error("--traffic must be between 0 (none) and 10");
  for (const std::string& name : o.datasets) {
    if (name == "none") continue;
    sim::makePreset(name, {.data_dir = o.data});  // an unknown name or missing data: fail early
  }
  // A place the tables cannot be written fails now, not after the runs.
  if (!o.markdown.empty()) io::TempFile probe(o.markdown);
  std::vector<DatasetRun> runs;
  std::vector<DatasetRun> scales;
  for (const std::uint64_t seed : o.seeds) {
    for (const std::string& preset : o.datasets) {
      if (preset == "none") continue;
      runs.push_back(runOne(preset, 0, seed, runName(preset, seed, o), o, config));
    }
    if (o.scale != "none") {
      const std::string preset =
          o.scale_robots > 0 ? fmt::format("{}-{}", o.scale, o.scale_robots) : o.scale;
      scales.push_back(runOne(o.scale, o.scale_robots, seed, runName(preset, seed, o), o, config));
      scales.back().preset = preset + " (large team)";
    }
  }
  const std::string text = tables(runs, scales, o.seeds.size() > 1);
  if (!o.markdown.empty()) io::writeFileAtomic(o.markdown, [&](std::ostream& out) { out << text; });
  if (!o.json) return fmt::print("{}", text);
  const auto boundJson = [](const DatasetRun& run) {
    Json out = Json::array();
    for (const RobotBound& r : run.bound) {
      out.push_back({{"name", r.name},
                     {"ate_odometry", r.odometry},
                     {"ate_own_slam", r.own_loops},
                     {"ate_system", r.run},
                     {"ate_joint_optimum", r.optimum},
                     {"ate_loops_exact", r.exact}});
    }
    return out;
  };
  Json all = Json::array();
  for (const DatasetRun& run : runs) {
    all.push_back(
        {{"summary", summaryOf(run)}, {"bound", boundJson(run)}, {"metrics", run.metrics}});
  }
  Json j = {{"datasets", all}, {"scale", Json::array()}};
  for (const DatasetRun& scale : scales) {
    j["scale"].push_back(
        {{"summary", summaryOf(scale)}, {"bound", boundJson(scale)}, {"metrics", scale.metrics}});
  }
  fmt::print("{}\n", j.dump(2));
}

}  // namespace

void addBenchSystemCommand(CLI::App& bench, const AppConfig& config) {
  auto o = std::make_shared<SystemOptions>();
  o->data = defaultDataDir();
  CLI::App* cmd = bench.add_subcommand(
      "system",
      "the paper's experiments on simulated datasets: ATE/ARE per robot with odometry only and "
      "with the whole system, transmitted kB/s and communication time, and the large-team run");
  cmd->add_option("--datasets", o->datasets, "presets to run (none: only the large team)")
      ->delimiter(',')
      ->capture_default_str();
  cmd->add_option("--scale", o->scale, "the large-team preset (none: skip)")->capture_default_str();
  cmd->add_option("--scale-robots", o->scale_robots,
                  "robots of the large-team run (0: the preset's; e.g. 27)")
      ->capture_default_str();
  cmd->add_option("--seeds", o->seeds,
                  "worlds to simulate each preset in, e.g. 1,2,3 (1: the presets' own; the "
                  "others' folders are named <preset>-s<seed>)")
      ->delimiter(',')
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  cmd->add_option("--work", o->work, "folder for the datasets (simulated once) and the runs")
      ->capture_default_str();
  cmd->add_option("--data", o->data, "the shared data folder (KITTI ground truth)")
      ->capture_default_str();
  cmd->add_option("--max-frames", o->max_frames, "scans per robot at most (0: all)")
      ->check(kNonNegative)
      ->capture_default_str();
  cmd->add_option("--threads", o->threads, "robots processed at once (0: every core)")
      ->capture_default_str();
  cmd->add_option("--settle", o->settle,
                  "s of simulated time at most each run goes on after its data while robots "
                  "still optimise")
      ->capture_default_str();
  cmd->add_option("--range", o->range,
                  "m, communication range (0: unlimited, the paper's assumption)")
      ->capture_default_str();
  cmd->add_option("--traffic", o->traffic,
                  "moving cars, cyclists and pedestrians, and cars parked for a while, in every "
                  "world: this times the world's own traffic (0: none; the folders get -t<D>)")
      ->capture_default_str();
  cmd->add_flag("--body-motion", o->body_motion,
                "the vehicles of generated routes rock on their suspension (simulate "
                "--body-motion; the folders get -b)");
  cmd->add_option("--markdown", o->markdown, "also write the tables to this file");
  cmd->add_flag("--json", o->json, "print every run's metrics and summary as JSON");
  cmd->callback([o, &config] { runSystem(*o, config); });
}

}  // namespace dcl::apps
