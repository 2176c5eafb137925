// `dcl-slam pcm`: PCM outlier rejection (paper §III-C) on the inter-robot loops
// of a multi-robot graph, robot pair by robot pair, scored against an
// outlier-free reference when one is given.
#include <chrono>
#include <memory>
#include <optional>
#include <set>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include <dcl/backend/loop_check.hpp>
#include <dcl/backend/pcm.hpp>
#include <dcl/backend/pcm_evaluation.hpp>
#include <dcl/core/error.hpp>
#include <dcl/io/multi_robot_graph.hpp>

#include "commands.hpp"
#include "printing.hpp"

namespace dcl::apps {

namespace {

using Json = nlohmann::ordered_json;
using Clock = std::chrono::steady_clock;

struct PcmOptions {
  std::string graph;      ///< g2o file or folder of per-robot N.g2o files
  std::string reference;  ///< outlier-free reference (file or folder), optional
  double threshold = 0.0;
  std::size_t min_loops = 1;        ///< PcmConfig::min_loops (1: PCM as published)
  bool check_loops = false;         ///< then withdraw what the joint solution cannot explain
  bool skip_unknown_lines = false;  ///< skip damaged lines of the graph's files
  bool json = false;
};

/// Loops and kept loops of a set of pairs, with precision and recall when scored.
Json counts(const backend::PcmResult& result,
            const std::optional<std::set<backend::LoopId>>& reference) {
  std::size_t unverified = 0;
  bool exact = true;
  for (const auto& p : result.pairs) {
    unverified += p.decision.unverified.size();
    exact = exact && p.decision.exact;
  }
  Json j = {{"loops", result.loops()},
            {"kept", result.accepted()},
            {"rejected", result.loops() - result.accepted()},
            {"unverified", unverified},
            {"exact", exact},
            {"precision", nullptr},
            {"recall", nullptr}};
  if (reference) {
    const backend::LoopScore s = backend::scoreLoops(result, *reference);
    j["precision"] = s.precision;
    j["recall"] = s.recall;
    j["inliers"] = s.inliers;
    j["true_kept"] = s.true_kept;
  }
  return j;
}

/// Loops as "a12-b3" (lower robot first), in key order.
Json loopNames(const std::vector<backend::Factor>& loops) {
  Json names = Json::array();
  for (const backend::Factor& f : loops) {
    const backend::LoopId id = backend::loopId(f);
    names.push_back(core::keyName(id.first) + "-" + core::keyName(id.second));
  }
  return names;
}

Json pairsJson(const backend::PcmResult& result,
               const std::optional<std::set<backend::LoopId>>& reference) {
  Json pairs = Json::array();
  for (const auto& p : result.pairs) {
    Json j = {{"robots", {core::robotName(p.robot_a), core::robotName(p.robot_b)}}};
    j.update(counts(backend::PcmResult{{p}}, reference));
    j["consistent_pairs"] = p.decision.consistent_pairs;
    j["kept_loops"] = loopNames(p.decision.accepted);
    j["rejected_loops"] = loopNames(p.decision.rejected);
    j["unverified_loops"] = loopNames(p.decision.unverified);
    pairs.push_back(j);
  }
  return pairs;
}

void printPcmSummary(const Json& m) {
  fmt::print("pcm '{}': {} robots, {} inter-robot loops, threshold {}\n",
             m["graph"].get<std::string>(), m["robots"].get<std::size_t>(),
             m["loops"].get<std::size_t>(), m["threshold"].get<double>());
  for (const Json& p : m["pairs"]) {
    fmt::print("  {}-{}: {} loops, {} kept, {} rejected{}{}\n", p["robots"][0].get<std::string>(),
               p["robots"][1].get<std::string>(), p["loops"].get<std::size_t>(),
               p["kept"].get<std::size_t>(), p["rejected"].get<std::size_t>(),
               p["unverified"].get<std::size_t>() > 0
                   ? fmt::format(" ({} beyond the odometry)", p["unverified"].get<std::size_t>())
                   : "",
               p["exact"].get<bool>() ? "" : " (heuristic clique)");
  }
  fmt::print("  total: {} kept, {} rejected, {:.3f} s\n", m["kept"].get<std::size_t>(),
             m["rejected"].get<std::size_t>(), m["seconds"].get<double>());
  if (m["precision"].is_null()) return;
  fmt::print("  against '{}': {} of the loops are inliers; precision {:.4f}, recall {:.4f}\n",
             m["reference"].get<std::string>(), m["inliers"].get<std::size_t>(),
             m["precision"].get<double>(), m["recall"].get<double>());
}

void runPcmCommand(const PcmOptions& o, backend::PcmConfig config,
                   const backend::LoopCheckConfig& check_config) {
  if (!(o.threshold > 0.0)) throw core::Error("--threshold must be positive");
  config.threshold = o.threshold;
  if (o.min_loops == 0) throw core::Error("--min-loops must be at least 1");
  config.min_loops = o.min_loops;
  const backend::PoseGraph graph = io::readMultiRobotGraph(o.graph, o.skip_unknown_lines);
  std::optional<std::set<backend::LoopId>> reference;
  if (!o.reference.empty()) reference = io::readReferenceLoops(o.reference, graph);
  const auto start = Clock::now();
  backend::PcmResult result = backend::runPcm(graph, config);
  const std::size_t withdrawn =
      o.check_loops ? backend::checkKeptLoops(graph, result, check_config) : 0;
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  Json m = {{"graph", o.graph},
            {"reference", o.reference.empty() ? Json(nullptr) : Json(o.reference)},
            {"robots", robotCount(graph)},
            {"threshold", config.threshold},
            {"min_loops", config.min_loops},
            {"check_loops", o.check_loops},
            {"withdrawn", withdrawn}};
  m.update(counts(result, reference));
  m["seconds"] = seconds;
  m["pairs"] = pairsJson(result, reference);
  if (o.json) return fmt::print("{}\n", m.dump(2));
  printPcmSummary(m);
}

}  // namespace

void addPcmCommand(CLI::App& app, const AppConfig& app_config) {
  auto* cmd = app.add_subcommand(
      "pcm",
      "PCM outlier rejection of the inter-robot loops of a multi-robot graph: loops kept and "
      "rejected per robot pair, precision and recall against an outlier-free reference");
  auto o = std::make_shared<PcmOptions>();
  o->threshold = app_config.pcm.threshold;
  cmd->add_option("--graph", o->graph,
                  "g2o file, or folder of per-robot graphs 0.g2o, 1.g2o, ... (symbol ids)")
      ->required();
  cmd->add_option("--reference", o->reference,
                  "the outlier-free graph: g2o file (symbol ids, or plain ids numbering robot "
                  "a's keyframes first) or folder of per-robot graphs");
  cmd->add_option("--threshold", o->threshold,
                  "largest squared Mahalanobis distance of a consistent loop pair")
      ->capture_default_str();
  cmd->add_option("--min-loops", o->min_loops,
                  "fewest mutually consistent loops of a robot pair before they are kept (1, the "
                  "default here: PCM as published; the SLAM pipeline uses pcm.min_loops)")
      ->capture_default_str();
  cmd->add_flag("--check-loops", o->check_loops,
                "then solve the graph with the kept loops, the robots' own factors held stiff, "
                "and withdraw the loops it cannot explain, at the robot pair with the least "
                "support (the second line of defence, loop_check)");
  cmd->add_flag("--skip-unknown-lines", o->skip_unknown_lines,
                "skip (and name) lines of the graph with an unknown tag instead of failing");
  cmd->add_flag("--json", o->json, "print the result as JSON");
  cmd->callback([o, &app_config] { runPcmCommand(*o, app_config.pcm, app_config.loop_check); });
}

}  // namespace dcl::apps
