// `dcl-slam pgo`: a pose graph solved the distributed way (DGS, then
// optionally the distributed refinement) or centrally (Ceres), with every
// distributed result reported beside the centralized optimum of the same graph.
#include <chrono>
#include <filesystem>
#include <memory>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/backend/centralized_solver.hpp>
#include <dcl/backend/dgs.hpp>
#include <dcl/backend/distributed_refine.hpp>
#include <dcl/backend/pcm_evaluation.hpp>
#include <dcl/backend/pose_graph.hpp>
#include <dcl/comm/messages.hpp>
#include <dcl/core/error.hpp>
#include <dcl/io/g2o.hpp>

#include "commands.hpp"

namespace dcl::apps {

namespace {

using Json = nlohmann::ordered_json;
using Clock = std::chrono::steady_clock;

struct PgoOptions {
  std::string g2o;             ///< a g2o file, or a folder of per-robot files
  int robots = 1;              ///< split a single-robot graph into this many
  std::string method = "dgs";  ///< centralized | dgs | dgs+refine
  std::string out;             ///< optional g2o of the result
  bool skip_unknown_lines = false;
  bool json = false;
};

/// Bytes on the wire per separator value. Ours: what one more estimate adds
/// to a comm::RotationEstimates or comm::PoseEstimates message (its keyframe
/// id as a varint and its fixed-point record: the relaxed rotation's nine
/// entries in int16, or a pose's quaternion in three int16 and translation in
/// float32), measured by encoding. The paper's code: a 3x3 float rotation
/// (36 B) or a 6-float pose vector (24 B), and an 8-byte GTSAM key each.
struct ValueBytes {
  std::size_t rotation = 0;
  std::size_t pose = 0;
};

ValueBytes ourBytes() {
  comm::Message rotations{{}, comm::RotationEstimates{}};
  comm::Message poses{{}, comm::PoseEstimates{}};
  rotations.header.sender = poses.header.sender = core::RobotId(0);
  const auto grow = [](comm::Message& m) {
    const std::size_t before = comm::encode(m).size();
    const core::KeyframeId id(1000);  // a typical keyframe id: two varint bytes
    if (auto* r = std::get_if<comm::RotationEstimates>(&m.body)) {
      r->rotations.emplace_back(id, Eigen::Matrix3d::Identity());
    } else {
      std::get<comm::PoseEstimates>(m.body).poses.emplace_back(id, Eigen::Isometry3d::Identity());
    }
    return comm::encode(m).size() - before;
  };
  grow(rotations);
  grow(poses);  // the first adds the fields' tags; the second is what each adds
  return {grow(rotations), grow(poses)};
}

constexpr ValueBytes kPaperBytes{8 + 36, 8 + 24};

double seconds(Clock::time_point since) {
  return std::chrono::duration<double>(Clock::now() - since).count();
}

std::size_t robotCount(const backend::PoseGraph& graph) {
  std::set<core::RobotId> robots;
  for (const auto& [key, pose] : graph.nodes()) robots.insert(key.robot);
  return robots.size();
}

backend::PoseGraph readGraph(const PgoOptions& o) {
  backend::PoseGraph graph = std::filesystem::is_directory(o.g2o)
                                 ? backend::readMultiRobotGraph(o.g2o, o.skip_unknown_lines)
                                 : backend::fromG2o(io::readG2o(o.g2o));
  if (o.robots < 1) throw core::Error("--robots must be at least 1");
  if (o.robots > 1) {
    if (robotCount(graph) != 1)
      throw core::Error("--robots splits a single-robot graph; '" + o.g2o + "' has " +
                        std::to_string(robotCount(graph)) + " robots already");
    graph = backend::splitIntoRobots(graph, o.robots);
  }
  return graph;
}

/// The centralized optimum from the chordal initialisation: the reference.
backend::SolverSummary centralized(backend::PoseGraph& graph) {
  backend::SolverConfig config;
  config.initialisation = "chordal";
  config.max_iterations = 500;
  config.function_tolerance = 1e-12;
  return backend::solveCentralized(graph, config);
}

Json runPgo(const PgoOptions& o, const backend::DgsConfig& dgs_config,
            const backend::RefineConfig& refine_config) {
  if (o.method != "centralized" && o.method != "dgs" && o.method != "dgs+refine")
    throw core::Error("unknown --method '" + o.method + "' (known: centralized, dgs, dgs+refine)");
  backend::PoseGraph graph = readGraph(o);
  backend::PoseGraph reference = graph;
  const backend::SolverSummary ref = centralized(reference);
  Json m = {{"graph", o.g2o},
            {"method", o.method},
            {"robots", robotCount(graph)},
            {"nodes", graph.size()},
            {"factors", graph.factors().size()},
            {"initial_cost", backend::graphCost(graph)}};
  m["centralized_cost"] = ref.final_cost;
  m["centralized_seconds"] = ref.time;
  if (o.method == "centralized") {
    graph = reference;
    m.update({{"cost", ref.final_cost},
              {"iterations_rotation", 0},
              {"iterations_pose", 0},
              {"rounds_refine", 0},
              {"bytes_total", 0},
              {"seconds", ref.time}});
  } else {
    const auto start = Clock::now();
    const backend::DgsSummary dgs = backend::runDgs(graph, dgs_config);
    m["cost_dgs"] = backend::graphCost(graph);
    const ValueBytes ours = ourBytes();
    std::size_t bytes =
        dgs.separator_values_rotation * ours.rotation + dgs.separator_values_pose * ours.pose;
    std::size_t paper = dgs.separator_values_rotation * kPaperBytes.rotation +
                        dgs.separator_values_pose * kPaperBytes.pose;
    int rounds = 0;
    m["seconds_dgs"] = dgs.seconds;
    m["seconds_refine"] = 0.0;
    if (o.method == "dgs+refine") {
      const backend::RefineSummary refine = backend::refineDistributed(graph, refine_config);
      rounds = refine.rounds;
      m["seconds_refine"] = refine.seconds;
      bytes += refine.separator_values * ours.pose;
      paper += refine.separator_values * kPaperBytes.pose;
    }
    const double cost = backend::graphCost(graph);
    m.update(
        {{"cost", cost},
         {"iterations_rotation", dgs.iterations_rotation},
         {"iterations_pose", dgs.iterations_pose},
         {"rounds_refine", rounds},
         {"separator_values", dgs.separator_values_rotation + dgs.separator_values_pose},
         {"bytes_total", bytes},
         {"bytes_paper_format", paper},
         {"bytes_per_robot", static_cast<double>(bytes) / static_cast<double>(robotCount(graph))},
         {"seconds", seconds(start)}});
  }
  m["cost_ratio"] = ref.final_cost > 0.0 ? m["cost"].get<double>() / ref.final_cost : 1.0;
  if (!o.out.empty()) io::writeG2o(o.out, backend::toG2o(graph));
  return m;
}

void printSummary(const Json& m) {
  fmt::print("{}: {} robots, {} nodes, {} factors; method {}\n", m["graph"].get<std::string>(),
             m["robots"].get<std::size_t>(), m["nodes"].get<std::size_t>(),
             m["factors"].get<std::size_t>(), m["method"].get<std::string>());
  if (m["method"] != "centralized") {
    fmt::print("  DGS: {} rotation and {} pose iterations, cost {:.6g}\n",
               m["iterations_rotation"].get<int>(), m["iterations_pose"].get<int>(),
               m["cost_dgs"].get<double>());
    fmt::print("  DGS {:.3f} s", m["seconds_dgs"].get<double>());
    if (m["rounds_refine"].get<int>() > 0)
      fmt::print(", refinement {} rounds in {:.3f} s", m["rounds_refine"].get<int>(),
                 m["seconds_refine"].get<double>());
    fmt::print("\n");
    fmt::print("  sent {} bytes ({:.0f} a robot; the paper's format: {} bytes)\n",
               m["bytes_total"].get<std::size_t>(), m["bytes_per_robot"].get<double>(),
               m["bytes_paper_format"].get<std::size_t>());
  }
  fmt::print("  cost {:.6g}, centralized {:.6g}: ratio {:.6f}; {:.3f} s (centralized {:.3f} s)\n",
             m["cost"].get<double>(), m["centralized_cost"].get<double>(),
             m["cost_ratio"].get<double>(), m["seconds"].get<double>(),
             m["centralized_seconds"].get<double>());
}

}  // namespace

void addPgoCommand(CLI::App& app, const AppConfig& config) {
  auto o = std::make_shared<PgoOptions>();
  CLI::App* cmd = app.add_subcommand(
      "pgo",
      "pose-graph optimisation, distributed (DGS, then optionally the distributed refinement) or "
      "centralized, with the cost ratio to the centralized optimum");
  cmd->add_option("--g2o", o->g2o,
                  "g2o file, or folder of per-robot graphs 0.g2o, 1.g2o, ... (symbol ids)")
      ->required();
  cmd->add_option("--robots", o->robots,
                  "split a single-robot graph into N robots by contiguous vertex ranges")
      ->capture_default_str();
  cmd->add_option("--method", o->method, "centralized, dgs or dgs+refine")->capture_default_str();
  cmd->add_option("--out", o->out, "write the optimised graph (g2o)");
  cmd->add_flag("--skip-unknown-lines", o->skip_unknown_lines,
                "skip (and name) lines of the graph with an unknown tag instead of failing");
  cmd->add_flag("--json", o->json, "print the result as JSON");
  cmd->callback([o, &config] {
    const Json m = runPgo(*o, config.dgs, config.refine);
    if (o->json) return fmt::print("{}\n", m.dump(2));
    printSummary(m);
  });
}

}  // namespace dcl::apps
