#include <algorithm>
#include <filesystem>
#include <functional>
#include <map>
#include <optional>
#include <string_view>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include <dcl/core/error.hpp>
#include <dcl/core/log.hpp>
#include <dcl/io/file.hpp>
#include <dcl/io/g2o.hpp>
#include <dcl/io/multi_robot_graph.hpp>
#include <dcl/io/pose_graph_g2o.hpp>

namespace dcl::io {
namespace {

namespace fs = std::filesystem;
using backend::Factor;
using backend::FactorKind;
using backend::LoopId;
using backend::PoseGraph;

/// A graph's odometry factors must be found in its reference at least this often.
constexpr double kMinOdometryMatch = 0.9;
/// Norm of log(T_reference^-1 T_graph) below which two measurements are the same
/// (text files print a few significant digits).
constexpr double kSameMeasurement = 1e-4;

/// One g2o file of a graph, as read.
struct GraphFile {
  std::string path;
  G2oGraph g2o;
};

/// Where a vertex is defined.
struct VertexSource {
  const GraphFile* file = nullptr;
  std::size_t line = 0;
};

GraphFile readGraphFile(const std::string& path, const G2oReadOptions& options) {
  GraphFile file{path, readG2o(path, options)};
  for (const std::size_t line : file.g2o.skipped_lines) {
    spdlog::warn("{}:{}: skipped a line with an unknown tag", path, line);
  }
  return file;
}

[[noreturn]] void failAt(const VertexSource& at, const std::string& what,
                         std::optional<std::string> field = std::nullopt) {
  throw core::FileError({.path = at.file->path, .line = at.line, .field = std::move(field)}, what);
}

/// A vertex id as a user reads it: "b12" for a symbol, the number otherwise.
std::string vertexName(std::uint64_t id) {
  return core::PoseKey::isSymbol(id) ? core::keyName(core::PoseKey::unpack(id))
                                     : std::to_string(id);
}

std::string describe(const VertexSource& at) {
  return fmt::format("{} line {}", fs::path(at.file->path).filename().string(), at.line);
}

/// The number of a robot graph's file name "<number>.g2o"; none for other names.
std::optional<std::uint64_t> robotNumber(const fs::path& path) {
  const std::string name = path.filename().string();
  if (name.size() < 5 || !name.ends_with(".g2o")) return std::nullopt;
  const std::string_view stem = std::string_view(name).substr(0, name.size() - 4);
  if (!std::all_of(stem.begin(), stem.end(), [](char c) { return c >= '0' && c <= '9'; }))
    return std::nullopt;
  const auto number = parseNumber<std::uint64_t>(stem);
  if (!number) throw core::FileError({.path = path.string()}, "robot number too large");
  return number;
}

/// The robot files of a split graph, 0.g2o, 1.g2o, ... in numeric order: each
/// a regular file, no number twice, none missing.
std::vector<std::string> robotFiles(const std::string& folder) {
  std::map<std::uint64_t, fs::path> files;
  for (const auto& entry : fs::directory_iterator(folder)) {
    const auto number = robotNumber(entry.path());
    if (!number) continue;
    if (!entry.is_regular_file()) {
      throw core::FileError({.path = entry.path().string()},
                            "is not a regular file (a robot's graph must be one)");
    }
    const auto [it, added] = files.emplace(*number, entry.path());
    if (!added) {
      throw core::FileError(
          {.path = folder},
          fmt::format("{} and {} are both robot graph {}", it->second.filename().string(),
                      entry.path().filename().string(), *number));
    }
  }
  if (files.empty()) {
    throw core::FileError({.path = folder}, "no robot graph (0.g2o, 1.g2o, ...) in this folder");
  }
  std::vector<std::string> paths;
  for (const auto& [number, path] : files) {
    if (number != paths.size()) {
      throw core::FileError({.path = folder},
                            fmt::format("{}.g2o is missing: robot graphs are numbered 0.g2o, "
                                        "1.g2o, ... without a gap (the next is {})",
                                        paths.size(), path.filename().string()));
    }
    paths.push_back(path.string());
  }
  return paths;
}

/// The file's vertices by the line that defines them.
std::vector<std::pair<std::size_t, std::uint64_t>> verticesByLine(const G2oGraph& g2o) {
  std::vector<std::pair<std::size_t, std::uint64_t>> vertices;
  for (const auto& [id, line] : g2o.vertex_lines) vertices.emplace_back(line, id);
  std::sort(vertices.begin(), vertices.end());
  return vertices;
}

/// The vertices of a split graph's files, checked as each file is added: a
/// file holds one robot's vertices and a robot's are in one file. A vertex
/// defined twice, of another robot than the first of its file, or of a robot
/// that another file holds, is an error naming the file and line.
class SplitVertices {
 public:
  /// Adds the vertices of `file` (which must outlive this).
  void add(const GraphFile& file) {
    std::optional<std::pair<core::RobotId, std::size_t>> holds;  // the file's robot, first line
    for (const auto& [line, id] : verticesByLine(file.g2o)) {
      const VertexSource here{&file, line};
      define(id, here);
      const core::RobotId robot = keyOfVertex(id).robot;
      if (!holds) holds = {claim(robot, here), line};
      if (robot == holds->first) continue;
      failAt(here,
             fmt::format("vertex {} is robot {}'s, but this file holds robot {}'s (line {})",
                         vertexName(id), core::robotName(robot), core::robotName(holds->first),
                         holds->second),
             "id");
    }
  }

  [[nodiscard]] bool contains(std::uint64_t id) const { return vertices_.contains(id); }

 private:
  void define(std::uint64_t id, const VertexSource& here) {
    const auto [defined, added] = vertices_.emplace(id, here);
    if (added) return;
    failAt(here,
           fmt::format("vertex {} is defined in {} already", vertexName(id),
                       describe(defined->second)),
           "id");
  }

  /// `robot`, whose first vertex is `here`, for the file of `here`.
  core::RobotId claim(core::RobotId robot, const VertexSource& here) {
    const auto [holder, added] = robots_.emplace(robot, here);
    if (added) return robot;
    failAt(here,
           fmt::format("robot {}'s vertices are in {} already (one file a robot)",
                       core::robotName(robot), describe(holder->second)),
           "id");
  }

  std::map<std::uint64_t, VertexSource> vertices_;
  std::map<core::RobotId, VertexSource> robots_;  ///< each robot's first vertex
};

/// Throws naming the file, line and end of the first edge of `file` to a vertex
/// that `defined` does not know; `who` completes "which ...".
void requireEdgeEnds(const GraphFile& file, const std::function<bool(std::uint64_t)>& defined,
                     std::string_view who) {
  for (const G2oEdge& e : file.g2o.edges) {
    for (const auto& [id, field] : {std::pair{e.from, "from"}, std::pair{e.to, "to"}}) {
      if (defined(id)) continue;
      throw core::FileError({.path = file.path, .line = e.line, .field = field},
                            fmt::format("edge to vertex {}, which {}", vertexName(id), who));
    }
  }
}

/// Adds `part` to `merged`: nodes, fixed nodes, factors; an inter-robot loop
/// whose keys `merged` holds already is left out.
void merge(PoseGraph& merged, const PoseGraph& part, std::set<LoopId>& loops) {
  for (const auto& [key, pose] : part.nodes()) merged.addNode(key, pose);
  for (const core::PoseKey& key : part.fixedNodes()) merged.fix(key);
  for (const Factor& f : part.factors()) {
    if (f.from.robot != f.to.robot && !loops.insert(backend::loopId(f)).second) continue;
    merged.addFactor(f);
  }
}

PoseGraph readGraphFolder(const std::string& folder, bool skip_unknown_lines) {
  // Not chained: a robot file without vertex lines defines no vertex.
  const G2oReadOptions options{.skip_unknown_tags = skip_unknown_lines,
                               .chain_missing_vertices = false};
  std::vector<GraphFile> files;
  for (const std::string& path : robotFiles(folder)) files.push_back(readGraphFile(path, options));
  SplitVertices vertices;
  for (const GraphFile& file : files) vertices.add(file);
  const auto defined = [&](std::uint64_t id) { return vertices.contains(id); };
  for (const GraphFile& file : files) {
    requireEdgeEnds(file, defined, "no robot graph of the folder defines");
  }
  PoseGraph merged;
  std::set<LoopId> loops;
  for (const GraphFile& file : files) merge(merged, toPoseGraph(file.g2o), loops);
  return merged;
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
std::vector<ReferenceEdge> mapEdges(const G2oGraph& g2o, const IdScheme& scheme) {
  const auto key = [&](std::uint64_t id) -> std::optional<core::PoseKey> {
    if (core::PoseKey::isSymbol(id)) return core::PoseKey::unpack(id);
    return scheme.key(id);
  };
  std::vector<ReferenceEdge> edges;
  for (const G2oEdge& e : g2o.edges) {
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
    const G2oGraph g2o = readG2o(path);
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
  if (fs::is_directory(path)) return readGraphFolder(path, skip_unknown_lines);
  const GraphFile file = readGraphFile(path, {.skip_unknown_tags = skip_unknown_lines});
  requireEdgeEnds(
      file, [&](std::uint64_t id) { return file.g2o.hasVertex(id); }, "the file does not define");
  return toPoseGraph(file.g2o);
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

}  // namespace dcl::io
