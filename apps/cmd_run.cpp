// `dcl-slam run`: every robot of a dataset in one process over the simulated
// radio (swarm::runSwarm), then the outputs of DESIGN.md §3: per-robot
// trajectories (TUM, KITTI), odometry and graph, metrics.json and report.html.
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <memory>
#include <numeric>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/backend/pose_graph.hpp>
#include <dcl/core/error.hpp>
#include <dcl/core/progress.hpp>
#include <dcl/eval/run_report.hpp>
#include <dcl/io/dataset.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/g2o.hpp>
#include <dcl/io/pose_file.hpp>
#include <dcl/sim/sim_source.hpp>
#include <dcl/swarm/swarm_run.hpp>

#include "commands.hpp"
#include "run_swarm.hpp"

namespace dcl::apps {
namespace {

using Json = nlohmann::ordered_json;

struct RunOptions {
  std::string dataset;
  std::string out = "out/run";
  std::size_t max_frames = 0;  ///< scans per robot, 0: all
  int threads = 0;             ///< 0: every core
  bool json = false;
};

robot::RobotConfig robotConfig(const AppConfig& c) {
  robot::RobotConfig r;
  r.odometry = c.odometry;
  r.mapper = c.mapper;
  r.descriptor = c.place.descriptor;
  r.index = c.place.evaluation.index;
  r.verification = c.verification;
  r.pcm = c.pcm;
  r.messenger = c.messenger;
  return r;
}

std::vector<swarm::SwarmMember> membersOf(const io::DatasetSpec& spec) {
  std::vector<std::unique_ptr<io::ScanSource>> scans = sim::openDatasetScans(spec);
  std::vector<swarm::SwarmMember> members;
  for (std::size_t r = 0; r < spec.robots.size(); ++r) {
    core::Trajectory truth;
    if (!spec.robots[r].ground_truth.empty()) truth = io::readGroundTruth(spec, r);
    members.push_back({spec.robots[r].name, std::move(scans[r]), spec.robots[r].start_time,
                       std::move(truth), std::nullopt});
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
    run.ground_truth = truths[r];
    run.frames = m.frames;
    run.keyframes = m.keyframes.size();
    run.intra_loops = static_cast<std::size_t>(counter(m.counters, "intra_loops"));
    run.inter_loops_accepted =
        static_cast<std::size_t>(counter(m.counters, "inter_loops_accepted"));
    run.inter_loops_rejected =
        static_cast<std::size_t>(counter(m.counters, "inter_loops_rejected"));
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

Json optionalJson(const std::optional<double>& value) {
  return value ? Json(*value) : Json(nullptr);
}

Json metricsJson(const eval::RunSummary& s, const std::vector<eval::RobotMetrics>& metrics,
                 const swarm::SwarmResult& result) {
  Json robots = Json::array();
  for (std::size_t r = 0; r < s.robots.size(); ++r) {
    const eval::RobotRun& run = s.robots[r];
    const eval::RobotMetrics& m = metrics[r];
    robots.push_back({{"name", run.name},
                      {"frames", run.frames},
                      {"keyframes", run.keyframes},
                      {"ate_rmse", optionalJson(m.ate_rmse)},
                      {"ate_rmse_odometry_only", optionalJson(m.ate_rmse_odometry_only)},
                      {"ate_rmse_joint", optionalJson(m.ate_rmse_joint)},
                      {"are_rmse_deg", optionalJson(m.are_rmse_deg)},
                      {"are_rmse_deg_odometry_only", optionalJson(m.are_rmse_deg_odometry_only)},
                      {"bytes_sent", run.bytes_sent},
                      {"bytes_received", run.bytes_received},
                      {"transmit_kBps", m.transmit_kBps},
                      {"receive_kBps", m.receive_kBps},
                      {"intra_loops", run.intra_loops},
                      {"inter_loops_accepted", run.inter_loops_accepted},
                      {"inter_loops_rejected", run.inter_loops_rejected},
                      {"counters", run.counters}});
  }
  return {{"dataset", s.dataset},
          {"duration_s", s.duration},
          {"radio_events", result.radio_events},
          {"robots", robots}};
}

void writeOutputs(const std::string& out, const eval::RunSummary& s,
                  const swarm::SwarmResult& result, const Json& metrics,
                  const std::vector<eval::RobotMetrics>& robot_metrics) {
  for (std::size_t r = 0; r < s.robots.size(); ++r) {
    const std::string folder = out + "/" + s.robots[r].name;
    std::filesystem::create_directories(folder);
    io::writeTumPoses(folder + "/trajectory.tum", s.robots[r].estimate);
    io::writeKittiPoses(folder + "/trajectory.kitti", s.robots[r].estimate, folder + "/times.txt");
    io::writeTumPoses(folder + "/odometry.tum", s.robots[r].odometry);
    io::writeG2o(folder + "/graph.g2o", backend::toG2o(result.robots[r].graph));
  }
  io::writeFileAtomic(out + "/metrics.json",
                      [&](std::ostream& out) { out << metrics.dump(2) << "\n"; });
  io::writeFileAtomic(out + "/report.html",
                      [&](std::ostream& out) { out << eval::reportHtml(s, robot_metrics); });
}

std::string metres(const Json& value) {
  return value.is_null() ? "-" : fmt::format("{:.3f}", value.get<double>());
}

}  // namespace

void printRunTable(const Json& m, const std::string& out) {
  fmt::print("{:<6} {:>7} {:>9} {:>10} {:>10} {:>6} {:>12} {:>10}\n", "robot", "frames",
             "keyframes", "ATE (m)", "odometry", "intra", "inter kept", "kB sent");
  for (const Json& r : m["robots"]) {
    fmt::print(
        "{:<6} {:>7} {:>9} {:>10} {:>10} {:>6} {:>7}/{:<4} {:>10.1f}\n",
        r["name"].get<std::string>(), r["frames"].get<std::size_t>(),
        r["keyframes"].get<std::size_t>(), metres(r["ate_rmse"]),
        metres(r["ate_rmse_odometry_only"]), r["intra_loops"].get<std::size_t>(),
        r["inter_loops_accepted"].get<std::size_t>(),
        r["inter_loops_accepted"].get<std::size_t>() + r["inter_loops_rejected"].get<std::size_t>(),
        static_cast<double>(r["bytes_sent"].get<std::size_t>()) / 1000.0);
  }
  fmt::print("outputs in {} (metrics.json, report.html, one folder per robot)\n", out);
}

Json runSwarmDataset(const std::string& dataset, const std::string& out, std::size_t max_frames,
                     int threads, const AppConfig& config) {
  const RunOptions o{dataset, out, max_frames, threads, false};
  const io::DatasetSpec spec = io::readDataset(o.dataset);
  std::vector<swarm::SwarmMember> members = membersOf(spec);
  std::vector<core::Trajectory> truths;
  for (const swarm::SwarmMember& m : members) truths.push_back(m.ground_truth);
  std::size_t total = 0;
  for (const swarm::SwarmMember& m : members)
    total += o.max_frames > 0 ? std::min(o.max_frames, m.scans->size()) : m.scans->size();

  swarm::SwarmConfig sc;
  sc.robot = robotConfig(config);
  sc.radio = config.radio;
  sc.max_frames = o.max_frames;
  sc.threads = o.threads;
  core::ProgressBar progress("run " + (spec.name.empty() ? o.dataset : spec.name), total, "frames");
  const swarm::SwarmResult result = swarm::runSwarm(
      std::move(members), sc, [&](double time, const std::vector<std::size_t>& done) {
        progress.update(std::accumulate(done.begin(), done.end(), std::size_t{0}),
                        fmt::format("t = {:.0f} s", time));
      });
  progress.finish();

  const eval::RunSummary summary = summaryOf(spec, result, truths, config.radio.meter_interval);
  const std::vector<eval::RobotMetrics> metrics = eval::evaluateRun(summary);
  const Json m = metricsJson(summary, metrics, result);
  writeOutputs(o.out, summary, result, m, metrics);
  return m;
}

void addRunCommand(CLI::App& app, const AppConfig& config) {
  auto o = std::make_shared<RunOptions>();
  CLI::App* cmd = app.add_subcommand(
      "run",
      "every robot of a dataset in one process over the simulated radio (range, bandwidth, "
      "latency and losses from the config's radio section), in lock-step simulated time, "
      "deterministic; writes trajectories, graphs, metrics.json and report.html");
  cmd->add_option("--dataset", o->dataset, "dataset folder (dataset.yaml)")->required();
  cmd->add_option("--out", o->out, "output folder")->capture_default_str();
  cmd->add_option("--max-frames", o->max_frames, "scans per robot at most (0: all)")
      ->capture_default_str();
  cmd->add_option("--threads", o->threads, "robots processed at once (0: every core)")
      ->capture_default_str();
  cmd->add_flag("--json", o->json, "print metrics.json instead of the table");
  cmd->callback([o, &config] {
    if (o->threads < 0) throw core::Error("--threads must be at least 0");
    const Json m = runSwarmDataset(o->dataset, o->out, o->max_frames, o->threads, config);
    if (o->json) return fmt::print("{}\n", m.dump(2));
    printRunTable(m, o->out);
  });
}

}  // namespace dcl::apps
