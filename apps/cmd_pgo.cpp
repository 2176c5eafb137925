// `dcl-slam pgo`: a pose graph solved the distributed way (DGS, then
// optionally the distributed refinement) or centrally (Ceres), with every
// distributed result reported beside the centralized optimum of the same graph.
#include <algorithm>
#include <chrono>
#include <map>
#include <memory>
#include <optional>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/backend/centralized_solver.hpp>
#include <dcl/backend/dgs.hpp>
#include <dcl/backend/distributed_refine.hpp>
#include <dcl/backend/pose_graph.hpp>
#include <dcl/comm/messages.hpp>
#include <dcl/core/error.hpp>
#include <dcl/io/multi_robot_graph.hpp>
#include <dcl/io/pose_graph_g2o.hpp>
#include <dcl/robot/dgs_wire.hpp>

#include "commands.hpp"
#include "printing.hpp"

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

/// Bytes a separator value takes in the paper's code: a 3x3 float rotation
/// (36 B) or a 6-float pose vector (24 B), and an 8-byte GTSAM key each.
struct ValueBytes {
  std::size_t rotation = 0;
  std::size_t pose = 0;
};

constexpr ValueBytes kPaperBytes{8 + 36, 8 + 24};

/// Chi-square a factor below which costs are rounding (costRatio).
constexpr double kCostFloor = 1e-12;

/// An empty refinement message from `from`: what every refinement message carries.
robot::RefineMessage refineMessage(core::RobotId from, std::optional<core::RobotId> to, int round) {
  robot::RefineMessage m;
  m.from = from;
  m.to = to;
  m.step = static_cast<std::uint32_t>(round);
  return m;
}

/// The encoded size of `body` sent by `from` (to `to`; none: broadcast),
/// header included, as a robot node sends it.
std::size_t wireBytes(core::RobotId from, std::optional<core::RobotId> to, comm::Body body) {
  comm::Message m{{}, std::move(body)};
  m.header.sender = from;
  m.header.receiver = to;
  m.header.sequence = 1000;  // a typical sequence number: two varint bytes
  return comm::encode(m).size();
}

/// A coarse share on the wire, as the refinement's messages are packed: a
/// message header (that of an empty refinement state), then per gradient
/// entry its node (robot and index as varints) and six float32, per
/// Gauss-Newton block its two nodes and its 36 float32 (21 for a diagonal
/// block, which is symmetric). No comm message carries it yet: this is the
/// size of that layout, not of an encoded message.
std::size_t coarseShareBytes(core::RobotId from, const backend::CoarseShare& share) {
  const auto varint = [](std::uint64_t v) {
    std::size_t n = 1;
    while (v >= 128) {
      v >>= 7;
      ++n;
    }
    return n;
  };
  const auto node = [&](const backend::CoarseNode& n) {
    return 1 + varint(static_cast<std::uint64_t>(n.second));
  };
  std::size_t bytes =
      wireBytes(from, std::nullopt, robot::toWire(refineMessage(from, std::nullopt, 0)));
  for (const auto& [n, g] : share.gradient) bytes += node(n) + 6 * sizeof(float);
  for (const auto& [ab, block] : share.hessian) {
    const std::size_t entries = ab.first == ab.second ? 21 : 36;
    bytes += node(ab.first) + node(ab.second) + entries * sizeof(float);
  }
  return bytes;
}

/// Everything the robots of a pgo run send, measured on the wire: DGS's
/// messages and the refinement's separators and cost shares encoded as a
/// robot node encodes them (robot/dgs_wire.hpp; later separators as
/// increments from the last values sent), the coarse grids and shares as
/// coarseShareBytes packs them.
class WireMeter {
 public:
  void dgs(const backend::DgsMessage& m) { add("dgs", wireBytes(m.from, m.to, robot::toWire(m))); }

  void separators(core::RobotId from, core::RobotId to, int round,
                  const backend::RefineTraffic::Poses& poses) {
    robot::RefineMessage m = refineMessage(from, to, round);
    m.poses = poses;
    auto& told = told_[{from, to}];
    m.increments = !told.empty() && std::all_of(poses.begin(), poses.end(), [&](const auto& p) {
      const auto base = told.find(p.first);
      return base != told.end() &&
             (base->second.translation() - p.second.translation()).cwiseAbs().maxCoeff() <
                 0.5 * comm::kMaxIncrement;
    });
    if (m.increments) {
      for (auto& [key, T] : m.poses) T = told.at(key).inverse() * T;
    }
    const comm::Body body = robot::toWire(m);
    remember(told, std::get<comm::PoseEstimates>(comm::asDelivered(body)), from, m.increments);
    add("refine_separators", wireBytes(from, to, body));
  }

  void cost(core::RobotId from, int round, double share) {
    robot::RefineMessage m = refineMessage(from, std::nullopt, round);
    m.cost_share = static_cast<float>(share);
    add("refine_costs", wireBytes(from, std::nullopt, robot::toWire(m)));
  }

  /// The priced lengths of a coarse step: a cost share's message carrying
  /// one float32 more for every scale after the first.
  void coarseCosts(core::RobotId from, int round, std::size_t scales) {
    robot::RefineMessage m = refineMessage(from, std::nullopt, round);
    m.cost_share = 1.0F;
    add("refine_costs",
        wireBytes(from, std::nullopt, robot::toWire(m)) + (scales - 1) * sizeof(float));
  }

  void grid(core::RobotId from, core::RobotId to) {
    // Origin and cell size in float32, the three node counts as one-byte varints.
    add("refine_coarse", wireBytes(from, to, robot::toWire(refineMessage(from, to, 0))) + 16 + 3);
  }

  void coarse(const backend::CoarseShare& share) {
    const std::size_t bytes = coarseShareBytes(share.robot, share);
    backend::CoarseShare gradient_only = share;
    gradient_only.hessian.clear();
    const std::size_t gradient = coarseShareBytes(share.robot, gradient_only);
    add("refine_coarse", gradient);
    add("refine_coarse_blocks", bytes - gradient);
  }

  [[nodiscard]] std::size_t total() const {
    std::size_t sum = 0;
    for (const auto& [kind, bytes] : bytes_) sum += bytes;
    return sum;
  }
  [[nodiscard]] const std::map<std::string, std::size_t>& byKind() const { return bytes_; }

  backend::DgsTraffic dgsTraffic() {
    return [this](const backend::DgsMessage& m) { dgs(m); };
  }

  backend::RefineTraffic refineTraffic() {
    backend::RefineTraffic t;
    t.separators = [this](core::RobotId f, core::RobotId to, int round, const auto& poses) {
      separators(f, to, round, poses);
    };
    t.cost = [this](core::RobotId f, int round, double share) { cost(f, round, share); };
    t.grid = [this](core::RobotId f, core::RobotId to, const backend::CoarseGrid&) { grid(f, to); };
    t.coarse = [this](int, const backend::CoarseShare& share) { coarse(share); };
    t.coarse_costs = [this](core::RobotId f, int round, const auto& costs) {
      coarseCosts(f, round, costs.size());
    };
    return t;
  }

 private:
  using Told = std::map<core::PoseKey, Eigen::Isometry3d>;

  void add(const std::string& kind, std::size_t bytes) { bytes_[kind] += bytes; }

  /// What the receiver now holds of the sender's poses (as it decodes them).
  static void remember(Told& told, const comm::PoseEstimates& delivered, core::RobotId from,
                       bool increments) {
    for (const auto& [id, T] : delivered.poses) {
      Eigen::Isometry3d& held = told[{from, id}];
      held = increments ? Eigen::Isometry3d(held * T) : T;
    }
  }

  std::map<std::string, std::size_t> bytes_;
  std::map<std::pair<core::RobotId, core::RobotId>, Told> told_;
};

backend::PoseGraph readGraph(const PgoOptions& o) {
  backend::PoseGraph graph = io::readMultiRobotGraph(o.g2o, o.skip_unknown_lines);
  if (o.robots < 1) throw core::Error("--robots must be at least 1");
  if (o.robots > 1) {
    if (robotCount(graph) != 1)
      throw core::Error("--robots splits a single-robot graph; '" + o.g2o + "' has " +
                        std::to_string(robotCount(graph)) + " robots already");
    // A graph of fewer nodes than robots gets one node a robot ("robots" in
    // the result says how many).
    const auto robots = std::min<std::size_t>(static_cast<std::size_t>(o.robots), graph.size());
    graph = backend::splitIntoRobots(graph, static_cast<int>(robots));
  }
  return graph;
}

/// cost / centralized, both raised by a floor of 1e-12 a factor: below it a
/// cost is rounding (a noise-free graph such as kitti_08 solves to 1e-21 or
/// 1e-19 depending on the order of the sums), and both answers are exact.
double costRatio(double cost, double centralized, std::size_t factors) {
  const double floor = kCostFloor * static_cast<double>(std::max<std::size_t>(factors, 1));
  return (cost + floor) / (centralized + floor);
}

/// The centralized optimum from the chordal initialisation: the reference.
backend::SolverSummary centralized(backend::PoseGraph& graph) {
  backend::SolverConfig config;
  config.initialisation = "chordal";
  config.max_iterations = 500;
  config.function_tolerance = 1e-12;
  return backend::solveCentralized(graph, config);
}

/// The centralized answer as the result (`--method centralized`).
void reportCentralized(Json& m, const backend::SolverSummary& ref) {
  m.update({{"cost", ref.final_cost},
            {"iterations_rotation", 0},
            {"iterations_pose", 0},
            {"rounds_refine", 0},
            {"bytes_total", 0},
            {"seconds", ref.time}});
}

/// DGS, then the refinement when asked, on `graph` in place; what they sent
/// measured on the wire, and the same values in the paper's format.
void runDistributed(Json& m, backend::PoseGraph& graph, const PgoOptions& o,
                    const backend::DgsConfig& dgs_config,
                    const backend::RefineConfig& refine_config) {
  const auto start = Clock::now();
  WireMeter meter;
  const backend::DgsSummary dgs = backend::runDgs(graph, dgs_config, {}, 0, meter.dgsTraffic());
  m["cost_dgs"] = backend::graphCost(graph);
  std::size_t paper = dgs.separator_values_rotation * kPaperBytes.rotation +
                      dgs.separator_values_pose * kPaperBytes.pose;
  backend::RefineSummary refine;
  if (o.method == "dgs+refine") {
    refine = backend::refineDistributed(graph, refine_config, meter.refineTraffic());
    paper += refine.separator_values * kPaperBytes.pose;
  }
  const std::size_t bytes = meter.total();
  m.update(
      {{"cost", backend::graphCost(graph)},
       {"iterations_rotation", dgs.iterations_rotation},
       {"iterations_pose", dgs.iterations_pose},
       {"rounds_refine", refine.rounds},
       {"restarts_refine", refine.restarts},
       {"separator_values", dgs.separator_values_rotation + dgs.separator_values_pose},
       {"separator_values_refine", refine.separator_values},
       {"bytes_total", bytes},
       {"bytes", meter.byKind()},
       {"bytes_paper_format", paper},
       {"bytes_per_robot", static_cast<double>(bytes) / static_cast<double>(robotCount(graph))},
       {"seconds_dgs", dgs.seconds},
       {"seconds_refine", refine.seconds},
       {"seconds", secondsSince(start)}});
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
    reportCentralized(m, ref);
  } else {
    runDistributed(m, graph, o, dgs_config, refine_config);
  }
  m["cost_ratio"] = costRatio(m["cost"].get<double>(), ref.final_cost, graph.factors().size());
  if (m.contains("cost_dgs")) {
    m["cost_ratio_dgs"] =
        costRatio(m["cost_dgs"].get<double>(), ref.final_cost, graph.factors().size());
  }
  if (!o.out.empty()) io::writePoseGraph(o.out, graph);
  return m;
}

void printPgoSummary(const Json& m) {
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
    printPgoSummary(m);
  });
}

}  // namespace dcl::apps
