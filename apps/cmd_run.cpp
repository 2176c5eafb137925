// `dcl-slam run`: every robot of a dataset in one process over the simulated
// radio (swarm::runSwarm), with a progress line per robot on a terminal, then
// the outputs of DESIGN.md §3: per-robot trajectories (TUM, KITTI), odometry,
// graph and map, the merged map coloured by robot, metrics.json and report.html.
#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <nlohmann/json.hpp>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/colour.hpp>
#include <dcl/core/error.hpp>
#include <dcl/core/progress.hpp>
#include <dcl/eval/loop_scoring.hpp>
#include <dcl/eval/run_report.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/ply.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/io/pose_graph_g2o.hpp>
#include <dcl/sim/sim_source.hpp>
#include <dcl/swarm/merged_map.hpp>
#include <dcl/swarm/swarm_progress.hpp>
#include <dcl/swarm/swarm_run.hpp>

#include "commands.hpp"
#include "front_end.hpp"
#include "live_view.hpp"
#include "option_checks.hpp"
#include "output_folder.hpp"
#include "printing.hpp"
#include "robot_outputs.hpp"
#include "run_swarm.hpp"

namespace dcl::apps {
namespace {

using Json = nlohmann::ordered_json;

struct RunOptions {
  std::string dataset;
  std::string out = "out/run";
  std::size_t max_frames = 0;                   ///< scans per robot, 0: all
  int threads = 0;                              ///< 0: every core
  double settle = swarm::SwarmConfig{}.settle;  ///< s at most after the data while robots optimise
  std::vector<std::string> leave;               ///< NAME@SECONDS, robots that leave mid-run
  bool json = false;
  bool force = false;  ///< replace --out even when it holds files of another program
};

/// The robots that leave mid-run, by name, from `--leave NAME@SECONDS`
/// options; throws core::Error naming the option value that is not one.
std::map<std::string, double> parseLeaves(const std::vector<std::string>& values,
                                          const io::DatasetSpec& spec) {
  std::map<std::string, double> out;
  for (const std::string& value : values) {
    const std::size_t at = value.rfind('@');
    const auto fail = [&value](const std::string& why) {
      throw core::Error(fmt::format("--leave '{}': {}", value, why));
    };
    if (at == std::string::npos) fail("expected NAME@SECONDS, e.g. b@60");
    const std::string name = value.substr(0, at);
    const std::string time = value.substr(at + 1);
    if (std::none_of(spec.robots.begin(), spec.robots.end(),
                     [&name](const io::RobotSpec& r) { return r.name == name; })) {
      std::vector<std::string> names;
      for (const io::RobotSpec& r : spec.robots) names.push_back(r.name);
      fail(fmt::format("no robot '{}' in the dataset (its robots: {})", name,
                       fmt::join(names, ", ")));
    }
    double seconds = 0.0;
    const char* end = time.data() + time.size();
    const auto [ptr, ec] = std::from_chars(time.data(), end, seconds);
    if (time.empty() || ec != std::errc() || ptr != end || !std::isfinite(seconds) || seconds < 0.0)
      fail(fmt::format("'{}' is not a time in seconds at or after the run's start", time));
    if (!out.emplace(name, seconds).second) fail(fmt::format("robot '{}' leaves twice", name));
  }
  return out;
}

std::vector<swarm::SwarmMember> membersOf(const io::DatasetSpec& spec,
                                          const std::map<std::string, double>& leave,
                                          const AppConfig& config, std::size_t max_frames) {
  std::vector<std::unique_ptr<io::ScanSource>> scans = sim::openDatasetScans(spec);
  std::vector<swarm::SwarmMember> members;
  for (std::size_t r = 0; r < spec.robots.size(); ++r) {
    core::Trajectory truth;
    if (!spec.robots[r].ground_truth.empty()) truth = io::readGroundTruth(spec, r);
    auto front_end = datasetFrontEnd(spec, r, *scans[r], max_frames, config.external);
    members.push_back({spec.robots[r].name, std::move(scans[r]), spec.robots[r].start_time,
                       std::move(truth), std::nullopt, std::move(front_end)});
    if (const auto it = leave.find(spec.robots[r].name); it != leave.end())
      members.back().leave_time = it->second;
  }
  return members;
}

/// The robot's keyframes as the graph now places them, and by odometry alone.
void trajectories(const swarm::MemberResult& m, core::RobotId id, core::Trajectory& estimate,
                  core::Trajectory& odometry) {
  for (const core::Keyframe& k : m.keyframes) {
    const core::PoseKey key{id, k.id};
    estimate.push_back(k.stamp, m.graph.hasNode(key) ? m.graph.estimate(key) : k.T_odom_keyframe);
    odometry.push_back(k.stamp, k.T_odom_keyframe);
  }
}

double counter(const std::map<std::string, double>& counters, const std::string& name) {
  const auto it = counters.find(name);
  return it == counters.end() ? 0.0 : it->second;
}

/// The ground truth of keyframe `key` at its stamp; none when the truth does not cover it.
std::optional<Eigen::Isometry3d> truthAt(const swarm::SwarmResult& result,
                                         const std::vector<core::Trajectory>& truths,
                                         const core::PoseKey& key) {
  const std::size_t r = key.robot.value();
  if (r >= truths.size() || truths[r].empty()) return std::nullopt;
  const std::vector<core::Keyframe>& keyframes = result.robots[r].keyframes;
  if (key.keyframe.value() >= keyframes.size()) return std::nullopt;
  return truths[r].at(keyframes[key.keyframe.value()].stamp);
}

/// The accepted inter-robot loops robot `r` is the lower robot of that the
/// ground truth says are wrong (more than 1 m or 2 deg off, as `bench loops`
/// grades them: eval::LoopTolerance); none when a robot has no ground truth.
std::optional<std::size_t> wrongAcceptedLoops(const swarm::SwarmResult& result,
                                              const std::vector<core::Trajectory>& truths,
                                              std::size_t r) {
  std::size_t wrong = 0;
  for (const robot::InterLoop& loop : result.robots[r].inter_loops) {
    const backend::Factor& f = loop.factor;
    if (!loop.accepted || std::min(f.from.robot, f.to.robot).value() != r) continue;
    const auto from = truthAt(result, truths, f.from);
    const auto to = truthAt(result, truths, f.to);
    if (!from || !to) return std::nullopt;
    wrong += eval::isCorrect(eval::loopError(f.T_from_to, *from, *to), {}) ? 0 : 1;
  }
  return wrong;
}

eval::RunSummary summaryOf(const io::DatasetSpec& spec, const swarm::SwarmResult& result,
                           const std::vector<core::Trajectory>& truths, double interval) {
  eval::RunSummary s;
  s.dataset = spec.name.empty() ? spec.folder : spec.name;
  s.meter_interval = interval;
  s.duration = result.duration;
  std::map<core::PoseKey, Eigen::Vector3d> positions;
  for (std::size_t r = 0; r < result.robots.size(); ++r) {
    const swarm::MemberResult& m = result.robots[r];
    const core::RobotId id(static_cast<std::uint8_t>(r));
    eval::RobotRun run;
    run.name = m.name;
    trajectories(m, id, run.estimate, run.odometry);
    // A robot whose frame is unknown (a round's initiator did not say) is in one of its own.
    run.frame = m.frame ? result.robots.at(m.frame->value()).name : "(unknown: " + m.name + ")";
    run.ground_truth = truths[r];
    run.frames = m.frames;
    run.keyframes = m.keyframes.size();
    run.intra_loops = static_cast<std::size_t>(counter(m.counters, "intra_loops"));
    run.inter_loops_accepted =
        static_cast<std::size_t>(counter(m.counters, "inter_loops_accepted"));
    run.inter_loops_rejected =
        static_cast<std::size_t>(counter(m.counters, "inter_loops_rejected"));
    run.inter_loops_accepted_wrong = wrongAcceptedLoops(result, truths, r);
    run.bytes_sent = m.traffic.sent;
    run.bytes_received = m.traffic.received;
    for (const auto& [kind, series] : m.sent_over_time)
      run.sent_over_time[std::string(comm::name(kind))] = series;
    run.counters = m.counters;
    for (std::size_t k = 0; k < run.estimate.size(); ++k)
      positions[{id, m.keyframes[k].id}] = run.estimate.pose(k).translation();
    s.robots.push_back(std::move(run));
  }
  // Each loop is known to both robots of its pair: draw it once, from the lower one's list.
  for (std::size_t r = 0; r < result.robots.size(); ++r) {
    for (const robot::InterLoop& loop : result.robots[r].inter_loops) {
      const core::PoseKey& a = loop.factor.from;
      const core::PoseKey& b = loop.factor.to;
      if (std::min(a.robot, b.robot).value() != r) continue;
      if (!positions.contains(a) || !positions.contains(b)) continue;
      s.loops.push_back(
          {a.robot.value(), b.robot.value(), positions.at(a), positions.at(b), loop.accepted});
    }
  }
  return s;
}

/// Each robot's map and all of them merged; empty when the run kept no map.
struct Maps {
  double voxel = 0.0;  ///< m
  std::vector<swarm::VoxelMap> robots;
  swarm::VoxelMap merged;
};

/// The keyframe clouds at the keyframes' final estimates (the trajectories' poses).
Maps buildMaps(const eval::RunSummary& s, const swarm::SwarmResult& result, double voxel) {
  Maps maps;
  maps.voxel = voxel;
  if (voxel <= 0.0) return maps;
  for (std::size_t r = 0; r < result.robots.size(); ++r) {
    const swarm::KeyframeClouds& clouds = result.robots[r].map_clouds;
    std::vector<Eigen::Isometry3d> poses;
    for (std::size_t k = 0; k < clouds.size(); ++k) poses.push_back(s.robots[r].estimate.pose(k));
    maps.robots.push_back(swarm::robotMap(clouds, poses, static_cast<std::uint8_t>(r)));
  }
  maps.merged = swarm::mergeMaps(maps.robots, voxel);
  return maps;
}

/// The robots' colours, so that the map and the report's plots agree.
io::Rgb robotColour(std::size_t robot) {
  const std::array<std::uint8_t, 3> c = core::robotColour(robot);
  return {c[0], c[1], c[2]};
}

void writeMap(const std::string& path, const swarm::VoxelMap& map) {
  std::vector<io::Rgb> colours;
  colours.reserve(map.size());
  for (const std::uint8_t r : map.robots) colours.push_back(robotColour(r));
  io::writeColouredPly(path, map.points, colours);
}

Json metricsJson(const eval::RunSummary& s, const std::vector<eval::RobotMetrics>& metrics,
                 const swarm::SwarmResult& result, const Maps& maps) {
  Json robots = Json::array();
  for (std::size_t r = 0; r < s.robots.size(); ++r) {
    const eval::RobotRun& run = s.robots[r];
    const eval::RobotMetrics& m = metrics[r];
    Json robot = robotMetricsJson(run, m);
    robot["map_points"] = maps.robots.empty() ? 0 : maps.robots[r].size();
    robot["map_cloud_bytes"] = result.robots[r].map_clouds.bytes();
    robot["counters"] = run.counters;
    robots.push_back(std::move(robot));
  }
  return {{"dataset", s.dataset},
          {"duration_s", s.duration},
          {"radio_events", result.radio_events},
          {"map_voxel_m", maps.voxel},
          {"map_points", maps.merged.size()},
          {"robots", robots}};
}

/// Writes `map` to `path`; without a map (map.voxel 0) removes what an earlier
/// run left there, so that the folder holds no map of another run.
void writeOrClearMap(const std::string& path, const swarm::VoxelMap* map) {
  if (map != nullptr) {
    writeMap(path, *map);
  } else {
    std::filesystem::remove(path);
  }
}

void writeOutputs(const std::string& out, const eval::RunSummary& s,
                  const swarm::SwarmResult& result, const Maps& maps, const Json& metrics,
                  const std::vector<eval::RobotMetrics>& robot_metrics) {
  for (std::size_t r = 0; r < s.robots.size(); ++r) {
    const std::string folder = out + "/" + s.robots[r].name;
    std::filesystem::create_directories(folder);
    io::writeTumPoses(folder + "/trajectory.tum", s.robots[r].estimate);
    io::writeKittiPoses(folder + "/trajectory.kitti", s.robots[r].estimate, folder + "/times.txt");
    io::writeTumPoses(folder + "/odometry.tum", s.robots[r].odometry);
    io::writePoseGraph(folder + "/graph.g2o", result.robots[r].graph);
    writeOrClearMap(folder + "/map.ply", maps.robots.empty() ? nullptr : &maps.robots[r]);
  }
  writeOrClearMap(out + "/map.ply", maps.robots.empty() ? nullptr : &maps.merged);
  io::writeFileAtomic(out + "/metrics.json",
                      [&](std::ostream& out) { out << metrics.dump(2) << "\n"; });
  io::writeFileAtomic(out + "/report.html",
                      [&](std::ostream& out) { out << eval::reportHtml(s, robot_metrics); });
}

/// The run, with a line per robot redrawn on a terminal (nothing otherwise).
swarm::SwarmResult runWithProgress(std::vector<swarm::SwarmMember> members,
                                   const swarm::SwarmConfig& config, const std::string& label,
                                   LiveView* view) {
  core::ProgressBoard board;
  swarm::SwarmStatus last;
  swarm::SwarmResult result =
      swarm::runSwarm(std::move(members), config, [&](const swarm::SwarmStatus& status) {
        if (view != nullptr) view->update(status);
        if (!board.enabled()) return;
        last = status;
        if (board.due()) board.draw(swarm::progressLines(label, status, board.elapsed()));
      });
  board.finish(swarm::progressLines(label, last, board.elapsed()));
  return result;
}

}  // namespace

void printRunTable(const Json& m, const std::string& out) {
  fmt::print("{:<6} {:>7} {:>9} {:>10} {:>10} {:>6} {:>12} {:>10}\n", "robot", "frames",
             "keyframes", "ATE (m)", "odometry", "intra", "inter kept", "kB sent");
  for (const Json& r : m["robots"]) {
    fmt::print(
        "{:<6} {:>7} {:>9} {:>10} {:>10} {:>6} {:>7}/{:<4} {:>10.1f}\n",
        r["name"].get<std::string>(), r["frames"].get<std::size_t>(),
        r["keyframes"].get<std::size_t>(), metresText(r["ate_rmse"]),
        metresText(r["ate_rmse_odometry_only"]), r["intra_loops"].get<std::size_t>(),
        r["inter_loops_accepted"].get<std::size_t>(),
        r["inter_loops_accepted"].get<std::size_t>() + r["inter_loops_rejected"].get<std::size_t>(),
        static_cast<double>(r["bytes_sent"].get<std::size_t>()) / 1000.0);
  }
  printFrames(m);
  std::size_t wrong = 0;
  bool graded = false;
  for (const Json& r : m["robots"]) {
    if (r["inter_loops_accepted_wrong"].is_null()) continue;
    graded = true;
    wrong += r["inter_loops_accepted_wrong"].get<std::size_t>();
  }
  if (graded) fmt::print("inter-robot loops kept that the ground truth calls wrong: {}\n", wrong);
  for (const Json& r : m["robots"]) {
    if (r.contains("left_at_s") && !r["left_at_s"].is_null())
      fmt::print("{} left the swarm at {} s: its outputs are what it held then\n",
                 r["name"].get<std::string>(), r["left_at_s"].get<double>());
  }
  fmt::print("outputs in {} ({}metrics.json, report.html, one folder per robot)\n", out,
             m["map_points"].get<std::size_t>() > 0 ? "map.ply, " : "");
}

Json runSwarmDataset(const std::string& dataset, const std::string& out, std::size_t max_frames,
                     int threads, double settle, const AppConfig& config,
                     const std::vector<std::string>& leave, const VizOptions& viz) {
  const RunOptions o{dataset, out, max_frames, threads, settle, leave, false, false};
  const io::DatasetSpec spec = io::readDataset(o.dataset, datasetReadOptions());
  const std::map<std::string, double> leave_times = parseLeaves(o.leave, spec);
  std::vector<swarm::SwarmMember> members = membersOf(spec, leave_times, config, o.max_frames);
  std::vector<core::Trajectory> truths;
  for (const swarm::SwarmMember& m : members) truths.push_back(m.ground_truth);

  swarm::SwarmConfig sc;
  sc.robot = robotConfig(config);
  sc.radio = config.radio;
  sc.max_frames = o.max_frames;
  sc.threads = o.threads;
  sc.settle = o.settle;
  sc.map = config.map;
  std::unique_ptr<LiveView> view;
  if (viz.port) {
    std::vector<std::string> names;
    for (const swarm::SwarmMember& m : members) names.push_back(m.name);
    view = std::make_unique<LiveView>(*viz.port, names, viz.wait);
  }
  const swarm::SwarmResult result = runWithProgress(
      std::move(members), sc, "run " + (spec.name.empty() ? o.dataset : spec.name), view.get());

  eval::RunSummary summary = summaryOf(spec, result, truths, config.radio.meter_interval);
  const std::vector<eval::RobotMetrics> metrics = eval::evaluateRun(summary);
  const Maps maps = buildMaps(summary, result, sc.map.voxel);
  summary.map_points = maps.merged.points;  // the report's picture of map.ply
  summary.map_robots = maps.merged.robots;
  Json m = metricsJson(summary, metrics, result, maps);
  for (Json& robot : m["robots"]) {
    const auto it = leave_times.find(robot["name"].get<std::string>());
    robot["left_at_s"] = it == leave_times.end() ? Json(nullptr) : Json(it->second);
  }
  writeOutputs(o.out, summary, result, maps, m, metrics);
  return m;
}

void addVizOptions(CLI::App& cmd, VizOptions& viz) {
  cmd.add_option("--viz", viz.port,
                 "serve the run live on this port of 127.0.0.1 to Foxglove or Lichtblick (Foxglove "
                 "WebSocket): each robot's path, newest scan, loops and counters");
  cmd.add_option("--viz-wait", viz.wait, "s to wait for a first viewer before the run starts")
      ->check(CLI::Range(0.0, 3600.0))
      ->capture_default_str();
}

void addRunCommand(CLI::App& app, const AppConfig& config) {
  auto o = std::make_shared<RunOptions>();
  CLI::App* cmd = app.add_subcommand(
      "run",
      "every robot of a dataset in one process over the simulated radio (range, bandwidth, "
      "latency and losses from the config's radio section), in lock-step simulated time, "
      "deterministic; writes trajectories, graphs, maps (map.ply: all robots, coloured), "
      "metrics.json and report.html");
  cmd->add_option("--dataset", o->dataset, "dataset folder (dataset.yaml)")->required();
  cmd->add_option("--out", o->out, "output folder")->capture_default_str();
  cmd->add_option("--max-frames", o->max_frames, "scans per robot at most (0: all)")
      ->check(kNonNegative)
      ->capture_default_str();
  cmd->add_option("--threads", o->threads, "robots processed at once (0: every core)")
      ->capture_default_str();
  cmd->add_option("--settle", o->settle,
                  "s of simulated time at most to go on after the data while robots still "
                  "optimise (large teams' last rounds)")
      ->capture_default_str();
  cmd->add_option("--leave", o->leave,
                  "NAME@SECONDS: robot NAME leaves the swarm for good at that time of the run "
                  "(a crash, a dead battery); repeat for several")
      ->type_name("NAME@SECONDS");
  cmd->add_flag("--json", o->json, "print metrics.json instead of the table");
  addForceFlag(*cmd, o->force);
  auto viz = std::make_shared<VizOptions>();
  addVizOptions(*cmd, *viz);
  cmd->callback([o, viz, &config] {
    if (o->threads < 0) throw core::Error("--threads must be at least 0");
    OutputFolder out(o->out, o->force);
    out.requireOutside(o->dataset, "the dataset");
    const Json m = runSwarmDataset(o->dataset, out.path(), o->max_frames, o->threads, o->settle,
                                   config, o->leave, *viz);
    out.commit();
    if (o->json) return fmt::print("{}\n", m.dump(2));
    printRunTable(m, out.out());
  });
}

}  // namespace dcl::apps
