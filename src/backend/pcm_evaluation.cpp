#include <algorithm>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <regex>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include <dcl/backend/pcm_evaluation.hpp>
#include <dcl/core/error.hpp>
#include <dcl/core/log.hpp>
#include <dcl/io/g2o.hpp>

namespace dcl::backend {
namespace {

namespace fs = std::filesystem;

/// A graph's odometry factors must be found in its reference at least this often.
constexpr double kMinOdometryMatch = 0.9;
/// Norm of log(T_reference^-1 T_graph) below which two measurements are the same
/// (text files print a few significant digits).
constexpr double kSameMeasurement = 1e-4;

/// The robot files of a split graph, in numeric order.
std::vector<fs::path> robotFiles(const std::string& folder) {
  static const std::regex name("[0-9]+\\.g2o");
  std::vector<std::pair<std::uint64_t, fs::path>> files;
  for (const auto& entry : fs::directory_iterator(folder)) {
    const std::string file = entry.path().filename().string();
    if (entry.is_regular_file() && std::regex_match(file, name) && file.size() < 20) {
      files.emplace_back(std::stoull(file), entry.path());
    }
  }
  if (files.empty()) {
    throw core::FileError({.path = folder}, "no robot graph (0.g2o, 1.g2o, ...) in this folder");
  }
  std::sort(files.begin(), files.end());
  std::vector<fs::path> paths;
  for (auto& [n, path] : files) paths.push_back(std::move(path));
  return paths;
}

/// Adds `part` to `merged`: new nodes, fixed nodes, factors; an inter-robot loop
/// whose keys `merged` holds already is left out.
void merge(PoseGraph& merged, const PoseGraph& part, std::set<LoopId>& loops) {
  for (const auto& [key, pose] : part.nodes()) {
    if (!merged.hasNode(key)) merged.addNode(key, pose);
  }
  for (const core::PoseKey& key : part.fixedNodes()) merged.fix(key);
  for (const Factor& f : part.factors()) {
    if (f.from.robot != f.to.robot && !loops.insert(loopId(f)).second) continue;
    merged.addFactor(f);
  }
}

/// Keyframes per robot of `graph` (largest keyframe + 1), by robot.
std::map<core::RobotId, std::uint64_t> robotSizes(const PoseGraph& graph) {
  std::map<core::RobotId, std::uint64_t> sizes;
  const auto see = [&](const core::PoseKey& key) {
    auto& size = sizes[key.robot];
    size = std::max(size, key.keyframe.value() + 1);
  };
  for (const auto& [key, pose] : graph.nodes()) see(key);
  for (const Factor& f : graph.factors()) see(f.from), see(f.to);
  return sizes;
}

/// How the plain vertex ids of a centralized reference name the graph's keys.
struct IdScheme {
  std::string description;                                         ///< for error messages
  std::function<std::optional<core::PoseKey>(std::uint64_t)> key;  ///< none: not the graph's
};

/// Robot a's keyframes first, then robot b's, ... (mixRobust's full graphs).
IdScheme consecutiveIds(const PoseGraph& graph) {
  std::map<std::uint64_t, std::pair<core::RobotId, std::uint64_t>> first_id;  // robot, size
  std::string description = "plain ids read as robot a's keyframes, then robot b's, ...:";
  std::uint64_t offset = 0;
  for (const auto& [robot, size] : robotSizes(graph)) {
    first_id.emplace(offset, std::make_pair(robot, size));
    description += fmt::format(" {} {}..{}", core::robotName(robot), offset, offset + size - 1);
    offset += size;
  }
  return {description, [first_id](std::uint64_t id) -> std::optional<core::PoseKey> {
            auto it = first_id.upper_bound(id);
            if (it == first_id.begin()) return std::nullopt;
            --it;
            const auto& [robot, size] = it->second;
            if (id - it->first >= size) return std::nullopt;
            return core::PoseKey{robot, core::KeyframeId(id - it->first)};
          }};
}

/// The plain id is the keyframe index, unique over the robots (distributed-mapper's
/// full graphs); maps nothing when two robots share an index.
IdScheme sharedIndexIds(const PoseGraph& graph) {
  std::map<std::uint64_t, core::PoseKey> keys;
  bool shared = true;
  for (const auto& [key, pose] : graph.nodes()) {
    const auto [it, added] = keys.emplace(key.keyframe.value(), key);
    shared = shared && (added || it->second == key);
  }
  if (!shared) keys.clear();
  return {shared ? "plain ids read as keyframe indices shared by all robots"
                 : "plain ids read as keyframe indices shared by all robots (they are not)",
          [keys](std::uint64_t id) -> std::optional<core::PoseKey> {
            const auto it = keys.find(id);
            if (it == keys.end()) return std::nullopt;
            return it->second;
          }};
}

/// An edge of the reference named by graph keys, with its measurement.
struct ReferenceEdge {
  core::PoseKey from;
  core::PoseKey to;
  Eigen::Isometry3d T_from_to;
};

/// The reference's edges under `scheme` (symbol ids as they are; unmapped ids left out).
std::vector<ReferenceEdge> mapEdges(const io::G2oGraph& g2o, const IdScheme& scheme) {
  const auto key = [&](std::uint64_t id) -> std::optional<core::PoseKey> {
    if (core::PoseKey::isSymbol(id)) return core::PoseKey::unpack(id);
    return scheme.key(id);
  };
  std::vector<ReferenceEdge> edges;
  for (const io::G2oEdge& e : g2o.edges) {
    const auto from = key(e.from);
    const auto to = key(e.to);
    if (from && to) edges.push_back({*from, *to, e.T_from_to});
  }
  return edges;
}

/// The measurement from the lower key to the higher one.
std::pair<LoopId, Eigen::Isometry3d> ordered(const core::PoseKey& from, const core::PoseKey& to,
                                             const Eigen::Isometry3d& T_from_to) {
  if (from < to) return {{from, to}, T_from_to};
  return {{to, from}, T_from_to.inverse()};
}

/// How many of the graph's odometry factors are edges of the reference between
/// the same keys with the same measurement, and how many there are.
std::pair<std::size_t, std::size_t> odometryMatches(const PoseGraph& graph,
                                                    const std::vector<ReferenceEdge>& reference) {
  std::map<LoopId, Eigen::Isometry3d> links;
  for (const ReferenceEdge& e : reference) links.insert(ordered(e.from, e.to, e.T_from_to));
  std::size_t odometry = 0, found = 0;
  for (const Factor& f : graph.factors()) {
    if (f.kind != FactorKind::odometry) continue;
    ++odometry;
    const auto [keys, T] = ordered(f.from, f.to, f.T_from_to);
    const auto it = links.find(keys);
    if (it != links.end() && core::logSE3(it->second.inverse() * T).norm() < kSameMeasurement) {
      ++found;
    }
  }
  return {found, odometry};
}

bool matches(const std::pair<std::size_t, std::size_t>& found_of) {
  return static_cast<double>(found_of.first) >=
         kMinOdometryMatch * static_cast<double>(found_of.second);
}

/// The reference's edges, named by graph keys: a folder's as they are, a
/// file's under the first id scheme that matches the graph's odometry (so a
/// reference of another graph, or a wrong id mapping, is caught).
std::vector<ReferenceEdge> referenceEdges(const std::string& path, const PoseGraph& graph) {
  std::vector<std::pair<std::string, std::vector<ReferenceEdge>>> candidates;
  if (fs::is_directory(path)) {
    const PoseGraph reference = readMultiRobotGraph(path);
    std::vector<ReferenceEdge> edges;
    for (const Factor& f : reference.factors()) edges.push_back({f.from, f.to, f.T_from_to});
    candidates.emplace_back("robot graphs of the folder", std::move(edges));
  } else {
    const io::G2oGraph g2o = io::readG2o(path);
    for (const IdScheme& scheme : {consecutiveIds(graph), sharedIndexIds(graph)}) {
      candidates.emplace_back(scheme.description, mapEdges(g2o, scheme));
    }
  }
  std::string tried;
  for (auto& [description, edges] : candidates) {
    const auto found_of = odometryMatches(graph, edges);
    if (matches(found_of)) return std::move(edges);
    tried += fmt::format("; {} of {} with {}", found_of.first, found_of.second, description);
  }
  throw core::FileError({.path = path},
                        "not a reference of this graph: too few of its odometry factors are "
                        "edges of the reference with the same measurement" +
                            tried);
}

}  // namespace

PoseGraph readMultiRobotGraph(const std::string& path, bool skip_unknown_lines) {
  if (!fs::exists(path)) throw core::FileError({.path = path}, "no such file or folder");
  const auto read = [&](const std::string& file) {
    const io::G2oGraph g2o = io::readG2o(file, {.skip_unknown_tags = skip_unknown_lines});
    for (const std::size_t line : g2o.skipped_lines) {
      spdlog::warn("{}:{}: skipped a line with an unknown tag", file, line);
    }
    return fromG2o(g2o);
  };
  if (!fs::is_directory(path)) return read(path);
  PoseGraph merged;
  std::set<LoopId> loops;
  for (const fs::path& file : robotFiles(path)) merge(merged, read(file.string()), loops);
  return merged;
}

std::set<LoopId> readReferenceLoops(const std::string& path, const PoseGraph& graph) {
  if (!fs::exists(path)) throw core::FileError({.path = path}, "no such file or folder");
  std::set<LoopId> loops;
  for (const ReferenceEdge& e : referenceEdges(path, graph)) {
    if (e.from.robot != e.to.robot) {
      loops.insert(e.from.robot < e.to.robot ? LoopId{e.from, e.to} : LoopId{e.to, e.from});
    }
  }
  return loops;
}

LoopScore scoreLoops(const PcmResult& result, const std::set<LoopId>& reference) {
  LoopScore s;
  for (const PcmPairResult& pair : result.pairs) {
    const PcmDecision& d = pair.decision;
    for (const auto* list : {&d.accepted, &d.rejected, &d.unverified, &d.withdrawn}) {
      for (const Factor& f : *list) {
        ++s.candidates;
        const bool inlier = reference.contains(loopId(f));
        s.inliers += inlier ? 1 : 0;
        if (list != &d.accepted) continue;
        ++s.kept;
        s.true_kept += inlier ? 1 : 0;
      }
    }
  }
  if (s.kept > 0) s.precision = static_cast<double>(s.true_kept) / static_cast<double>(s.kept);
  if (s.inliers > 0) s.recall = static_cast<double>(s.true_kept) / static_cast<double>(s.inliers);
  return s;
}

}  // namespace dcl::backend
